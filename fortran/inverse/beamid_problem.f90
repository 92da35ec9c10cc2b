!> One inverse problem from any list of experiment families (issue 13, 25).
!!
!! `inverse_problem_t` (alias `problem_t` of issue 25; beamid_dyn_diagnosis
!! keeps its own `problem_t`, the marshalled problem, so callers there use
!! the old name) is a `residual_model_t` whose data rows belong to
!! experiment families (beamid_family: the static experiments of
!! beamid_static_experiments, the arc-length solver, Eq. 40-56; the release
!! experiments of beamid_dynamic_experiments, the finite element dynamics,
!! Eq. 107, 135-140, 159-162; any family registered in beamid_families). It
!! holds a list of families, each built on its own experiments and rows;
!! `evaluate` asks each family for all its rows (one call per family) and
!! scatters them back in data order, so `fit_least_squares`, `score_test`
!! and `diagnose` serve any mix.
!!
!! Experiments cross as a kind (EXP_TIP, EXP_WIRE, EXP_RELEASE, ...: the
!! family that claims it) and a spec (experiment_spec_t of beamid_family:
!! named keys, EV_* their identifiers); rows as (experiment, t, observation), the observation an
!! index into the problem's observation list (beamid_observations: a kind
!! and its locus; without a list, the index is the kind code). Rows of an
!! untimed family need t = 0; duplicate (experiment, t, observation) rows
!! are rejected, naming the row.
!!
!! The measurement chain (issue 29): an experiment's spec may ask
!! for nuisance parameters, fitted with the physics as extra columns: a
!! clock offset t0 of a timed family's record (key t0 = 1: row i is the
!! model at time t_i + t0, so t0 is the model time at the record's zero;
!! column s h'(t_i + t0), the observation's rate from the family; the
!! accelerations have none, and a time offset on a record with such rows is
!! an input error), and per channel (experiment, observation) a bias b and a
!! scale s (bit q - 1 of keys bias, scale for entry q of the observation
!! list, so without a list for kind code q: the row reads s h + b; columns 1
!! and h), and a release's initial tip normal velocity v0 (key v0 = 1: the
!! static shape q starts with the velocity field v0 q / w_tip(q); column s
!! dh/dv0 from the family's sensitivities started at (0, q / w_tip(q))).
!! They follow the model's parameters in the parameter vector, in the order
!! of chain_layout: per experiment its t0, its v0, its biases by entry of
!! the observation list, its scales likewise. Null values t0 = 0, v0 = 0,
!! b = 0, s = 1 (the perfect chain), so the score test and refits of
!! beamid_estimation treat them as effects.
module beamid_problem
    use, intrinsic :: iso_fortran_env, only: int64
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, STATUS_OK, ERR_INPUT, fmt_int, fmt_real
    use beamid_estimation, only: residual_model_t, prior_t, lsq_problem_t, prior_from_covariance
    use beamid_observations, only: observation_t, obs_label, same_observation, MODE_STRIDE, &
                                   default_observations, KINDS
    use beamid_effects, only: effect_bounds, effect_null_values
    use beamid_chain_fit, only: chain_rows_t
    use beamid_family, only: family_slot_t, EXP_TIP, EXP_WIRE, EXP_RELEASE, EV_FX, EV_FY, &
                             EV_MOMENT, EV_WIRE_LENGTH, EV_NEPB, EV_GAIN, EV_METHOD, EV_LAW, &
                             EV_RTOL, EV_DT, EV_VSLIP, EV_FD, EV_T0, EV_BIAS, EV_SCALE, EV_LOSS, &
                             EV_BURNIN, EV_SIGEST, NEXPVAL, EV_V0, experiment_spec_t
    use beamid_families, only: registered_families, family_of_kind, kind_timed, kinds_expected
    use beamid_family, only: experiment_family_t, family_input_t
    use beamid_dynamic_experiments, only: dynamic_experiments_t, exp_histories_t, &
                                          attach_histories
    use beamid_family, only: SPEC_KEYS
    implicit none
    private

    public :: inverse_problem_t, problem_t, inverse_problem_init, inverse_lsq
    public :: observation_list, problem_from_arrays, problem_lsq_from_arrays
    public :: specs_from_triples
    public :: chain_layout
    !> The spec and its keys (beamid_family), here for the problem's callers.
    public :: experiment_spec_t, EXP_TIP, EXP_WIRE, EXP_RELEASE, EV_FX, EV_FY, EV_MOMENT, EV_WIRE_LENGTH, EV_NEPB, &
              EV_GAIN, EV_METHOD, EV_LAW, EV_RTOL, EV_DT, EV_VSLIP, EV_FD, EV_T0, EV_BIAS, &
              EV_SCALE, EV_LOSS, EV_BURNIN, EV_SIGEST, NEXPVAL, EV_V0

    !> Kinds of the nuisance parameters (chain_layout).
    integer, parameter, public :: NU_T0 = 1, NU_BIAS = 2, NU_SCALE = 3, NU_V0 = 4
    !> A channel mask is a whole number in a double: bits for the first 52
    !! entries of the observation list at most.
    integer, parameter, public :: MAX_CHANNEL_BITS = 52

    type, extends(residual_model_t) :: inverse_problem_t
        integer :: nrow = 0
        !> the families that have experiments, in the registry's order
        type(family_slot_t), allocatable :: fams(:)
        !> each experiment's family (index in fams) and number in its family
        integer, allocatable :: exp_fam(:), exp_loc(:)
        real(dp) :: tol = 0.0_dp           !< static solver tolerance (0: default)
        type(observation_t), allocatable :: obs(:)  !< the observation of each row
        !> physical bounds and null (switched-off) values of every parameter:
        !! they belong to the model, whatever the experiments
        real(dp), allocatable :: lower(:), upper(:), nulls(:)
        !> the model's parameter count; the nuisance parameters follow it
        integer :: np = 0
        !> nuisance parameters (chain_layout): kind NU_*, experiment, entry
        !! of the observation list
        integer, allocatable :: nu_kind(:), nu_exp(:), nu_q(:)
        !> per data row the index in the parameter vector of its record's
        !! clock offset, its channel's bias and scale (0: none)
        integer, allocatable :: row_t0(:), row_bias(:), row_scale(:)
        !> per data row the index of its release's initial velocity (0: none)
        integer, allocatable :: row_v0(:)
        type(chain_rows_t) :: rows        !< each row's loss, burn-in, estimated sigma
    contains
        procedure :: evaluate => inverse_evaluate
        procedure :: timed => problem_timed
    end type inverse_problem_t

    !> The issue's name for the problem of a list of families.
    type, extends(inverse_problem_t) :: problem_t
    end type problem_t

contains

    !> Build the problem: each family that has experiments built on their
    !! rows (experiment_family_t%setup, which calls the family's build).
    !! row_quantity(i) indexes obs, the problem's observation list (absent:
    !! the kind codes, beamid_observations default_observations).
    !! probe = .true.: rows that only predict (a diagnosis's probe rows on
    !! the data problem's experiments and chain): a channel of the chain or
    !! of an estimated sigma need not have rows among them.
    subroutine inverse_problem_init(nbeams, exp_kind, specs, row_exp, row_t, &
                                    row_quantity, tol, self, stat, obs, probe, hist)
        integer, intent(in) :: nbeams
        integer, intent(in) :: exp_kind(:), row_exp(:), row_quantity(:)
        !> each experiment's spec (beamid_family experiment_spec_t)
        type(experiment_spec_t), intent(in) :: specs(:)
        real(dp), intent(in) :: row_t(:), tol
        type(inverse_problem_t), intent(out) :: self
        type(status_t), intent(inout) :: stat
        type(observation_t), intent(in), optional :: obs(:)
        logical, intent(in), optional :: probe
        !> load histories of the release experiments (their own list beside
        !! the specs; beamid_dynamic_experiments exp_histories_t)
        type(exp_histories_t), intent(in), optional :: hist
        type(observation_t), allocatable :: list(:), robs(:)
        character(len=*), parameter :: where = 'experiments'
        type(family_slot_t), allocatable :: reg(:)
        integer, allocatable :: efam(:), eloc(:), fmap(:), fexp(:), frows(:)
        integer :: e, i, j, f, nf
        logical :: probing
        if (size(specs) /= size(exp_kind)) then
            call set_status(stat, ERR_INPUT, where, fmt_int(size(specs))//' experiment '// &
                            'specs, expected one per experiment ('//fmt_int(size(exp_kind))//')')
            return
        end if
        if (size(row_t) /= size(row_exp) .or. size(row_quantity) /= size(row_exp)) then
            call set_status(stat, ERR_INPUT, where, 'row experiment, t and quantity lists '// &
                            'differ in length')
            return
        end if
        probing = .false.
        if (present(probe)) probing = probe
        if (present(obs)) then
            list = obs
        else
            list = default_observations()
        end if
        do i = 1, size(row_quantity)
            if (row_quantity(i) < 1 .or. row_quantity(i) > size(list)) then
                call set_status(stat, ERR_INPUT, where, 'row '//fmt_int(i)//' has observation '// &
                                fmt_int(row_quantity(i))//', expected 1..'//fmt_int(size(list)))
                return
            end if
        end do
        robs = list(row_quantity)
        ! each experiment to the family that claims its kind
        call registered_families(reg)
        allocate (efam(size(exp_kind)), eloc(size(exp_kind)), source=0)
        do e = 1, size(exp_kind)
            efam(e) = family_of_kind(reg, exp_kind(e))
            if (efam(e) == 0) then
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)//' has '// &
                                'kind '//fmt_int(exp_kind(e))//', expected '//kinds_expected())
                return
            end if
            eloc(e) = count(efam(1:e) == efam(e))
        end do
        do i = 1, size(row_exp)
            if (row_exp(i) < 1 .or. row_exp(i) > size(exp_kind)) then
                call set_status(stat, ERR_INPUT, where, 'row '//fmt_int(i)//' names '// &
                                'experiment '//fmt_int(row_exp(i))//', expected 1..'// &
                                fmt_int(size(exp_kind)))
                return
            end if
            if (.not. reg(efam(row_exp(i)))%item%timed() .and. row_t(i) /= 0.0_dp) then
                call set_status(stat, ERR_INPUT, where, 'row '//fmt_int(i)//': field t = '// &
                                fmt_real(row_t(i))//', expected 0 for the '// &
                                reg(efam(row_exp(i)))%item%name()//' experiment '// &
                                fmt_int(row_exp(i)))
                return
            end if
            do j = 1, i - 1
                if (row_exp(j) == row_exp(i) .and. row_t(j) == row_t(i) .and. &
                    same_observation(robs(j), robs(i))) then
                    call set_status(stat, ERR_INPUT, where, 'row '//fmt_int(i)// &
                                    ' repeats row '//fmt_int(j)//' (experiment '// &
                                    fmt_int(row_exp(i))//', t = '//fmt_real(row_t(i))// &
                                    ', quantity '//obs_label(robs(i))//')')
                    return
                end if
            end do
        end do
        self%nrow = size(row_exp)
        self%tol = tol
        self%obs = robs
        call effect_bounds(nbeams, self%lower, self%upper)
        call effect_null_values(nbeams, self%nulls)
        call chain_init(stat)
        if (stat%code /= STATUS_OK) return
        call rows_init(stat)
        if (stat%code /= STATUS_OK) return
        ! the families that have experiments, each built on its own
        ! experiments and rows (numbered in the family)
        nf = 0
        allocate (fmap(size(reg)), source=0)
        do f = 1, size(reg)
            if (any(efam == f)) then
                nf = nf + 1
                fmap(f) = nf
            end if
        end do
        allocate (self%fams(nf))
        do f = 1, size(reg)
            if (fmap(f) == 0) cycle
            call move_alloc(reg(f)%item, self%fams(fmap(f))%item)
        end do
        self%exp_fam = fmap(efam)
        self%exp_loc = eloc
        self%plain_trials = .false.
        self%rough_jacobian_ok = .false.
        do f = 1, nf
            fexp = pack([(e, e=1, size(exp_kind))], self%exp_fam == f)
            frows = pack([(i, i=1, size(row_exp))], self%exp_fam(row_exp) == f)
            call self%fams(f)%item%setup(family_input_t(nbeams, exp_kind(fexp), &
                                                        specs(fexp), &
                                                        eloc(row_exp(frows)), row_t(frows), &
                                                        robs(frows), tol), frows, fexp, stat)
            if (stat%code /= STATUS_OK) then
                call renumber(frows)
                return
            end if
            associate (fam => self%fams(f)%item)
                fam%want_rates = any(self%nu_kind == NU_T0)
                ! a family of integrated responses: the fit judges its trial
                ! steps on predictions alone; one whose columns can be rough
                ! (releases on the implicit integrator, ROUGH_RTOL) steers
                ! the fit with rough sensitivities
                self%plain_trials = self%plain_trials .or. fam%plain_trials
                self%rough_jacobian_ok = self%rough_jacobian_ok .or. fam%rough_jacobian_ok
            end associate
            if (present(hist)) call histories_init(self%fams(f)%item, fexp, stat)
            if (stat%code /= STATUS_OK) return
        end do
    contains
        !> The load histories of the release family's experiments (fexp their
        !! numbers in the problem), each checked against its experiment's
        !! last row (an experiment without rows here, as in a probe problem:
        !! not checked); a history on another family's experiment is an error.
        subroutine histories_init(fam, fexp, stat)
            class(experiment_family_t), intent(inout) :: fam
            integer, intent(in) :: fexp(:)
            type(status_t), intent(inout) :: stat
            integer :: k, e
            if (.not. allocated(hist%spec)) return
            do k = 1, size(hist%spec, 2)
                e = nint(hist%spec(1, k))
                if (e < 1 .or. e > size(exp_kind)) then
                    call set_status(stat, ERR_INPUT, where, 'load history '//fmt_int(k)// &
                                    ' names experiment '//fmt_int(e)//', expected 1..'// &
                                    fmt_int(size(exp_kind)))
                    return
                end if
                if (exp_kind(e) /= EXP_RELEASE) then
                    call set_status(stat, ERR_INPUT, where, 'load history '//fmt_int(k)// &
                                    ' on experiment '//fmt_int(e)//', a static '// &
                                    'experiment: histories act on dynamic experiments only')
                    return
                end if
            end do
            select type (fam)
            type is (dynamic_experiments_t)
                do k = 1, size(fexp)
                    e = fexp(k)
                    call attach_histories(hist, e, merge(maxval(row_t, mask=row_exp == e), &
                                                         huge(1.0_dp), any(row_exp == e)), &
                                          fam%exps(k), stat)
                    if (stat%code /= STATUS_OK) return
                end do
            end select
        end subroutine histories_init

        !> Each row's loss, burn-in and estimated sigma (keys loss, burn_in,
        !! sigma_est), checked: a loss code 0..2, a burn-in time >= 0 on a
        !! release only, a channel mask whose channels have rows.
        subroutine rows_init(stat)
            type(status_t), intent(inout) :: stat
            integer :: e, q, nchan, i
            real(dp) :: v
            integer(int64) :: mask
            allocate (self%rows%loss(size(row_exp)), self%rows%channel(size(row_exp)), source=0)
            allocate (self%rows%fitted(size(row_exp)), source=.true.)
            nchan = 0
            do e = 1, size(exp_kind)
                v = specs(e)%get(EV_LOSS)
                if (.not. (v == 0.0_dp .or. v == 1.0_dp .or. v == 2.0_dp)) then
                    call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                    ': loss code = '//fmt_real(v)//', expected 0 (linear), '// &
                                    '1 (huber) or 2 (cauchy)')
                    return
                end if
                v = specs(e)%get(EV_BURNIN)
                if (.not. (v >= 0.0_dp .and. v < huge(1.0_dp))) then
                    call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                    ': burn-in = '//fmt_real(v)//', expected a time >= 0')
                    return
                end if
                if (v > 0.0_dp .and. .not. reg(efam(e))%item%timed()) then
                    call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                    ': a burn-in asked for a '//reg(efam(e))%item%name()// &
                                    ' experiment (only a release has a record in time)')
                    return
                end if
                v = specs(e)%get(EV_SIGEST)
                if (.not. channel_mask_ok(v, size(list))) then
                    call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                    ': sigma channel mask = '//fmt_real(v)//', expected '// &
                                    channel_mask_range(size(list)))
                    return
                end if
                where (row_exp == e) self%rows%loss = specs(e)%get_int(EV_LOSS)
                where (row_exp == e .and. row_t < specs(e)%get(EV_BURNIN)) &
                    self%rows%fitted = .false.
                mask = nint(v, int64)
                do q = 1, min(size(list), MAX_CHANNEL_BITS)
                    if (.not. btest(mask, q - 1)) cycle
                    if (.not. any(row_exp == e .and. row_quantity == q) .and. &
                        .not. probing) then
                        call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                        ': sigma of observation '//obs_label(list(q))// &
                                        ' to be estimated, but the experiment has no rows '// &
                                        'of that observation')
                        return
                    end if
                    nchan = nchan + 1
                    where (row_exp == e .and. row_quantity == q) self%rows%channel = nchan
                end do
            end do
            do i = 1, size(row_exp)
                if (self%rows%fitted(i)) return
            end do
            if (size(row_exp) > 0) call set_status(stat, ERR_INPUT, where, 'the burn-in '// &
                                                   'leaves no row to fit')
        end subroutine rows_init

        !> The nuisance parameters of the measurement chain, checked against
        !! the experiments and rows: their layout, bounds, null values and
        !! the rows each one acts on.
        subroutine chain_init(stat)
            type(status_t), intent(inout) :: stat
            integer :: k, i, e
            self%np = size(self%lower)
            call chain_layout(exp_kind, specs, self%nu_kind, self%nu_exp, self%nu_q, stat, &
                              size(list))
            if (stat%code /= STATUS_OK) return
            do k = 1, size(self%nu_kind)
                if (self%nu_kind(k) == NU_T0) then
                    ! the t0 column is the rows' time derivative: refuse a
                    ! record whose rows include an observation without one
                    do i = 1, size(row_exp)
                        if (row_exp(i) /= self%nu_exp(k)) cycle
                        if (KINDS(robs(i)%kind)%rate) cycle
                        call set_status(stat, ERR_INPUT, where, 'experiment '// &
                                        fmt_int(self%nu_exp(k))//': a time offset asked, '// &
                                        'but row '//fmt_int(i)//' observes '// &
                                        obs_label(robs(i))//', whose rate (the jerk) the '// &
                                        'fit does not compute yet; expected no time offset '// &
                                        'on a record with acceleration or load-cell rows')
                        return
                    end do
                    cycle
                end if
                if (self%nu_kind(k) == NU_V0) cycle
                if (any(row_exp == self%nu_exp(k) .and. row_quantity == self%nu_q(k))) cycle
                if (probing) cycle
                call set_status(stat, ERR_INPUT, where, 'experiment '// &
                                fmt_int(self%nu_exp(k))//': a '// &
                                trim(merge('bias ', 'scale', self%nu_kind(k) == NU_BIAS))// &
                                ' of observation '//obs_label(list(self%nu_q(k)))// &
                                ', but the experiment has no rows of that observation')
                return
            end do
            self%lower = [self%lower, (-huge(1.0_dp), k=1, size(self%nu_kind))]
            self%upper = [self%upper, (huge(1.0_dp), k=1, size(self%nu_kind))]
            self%nulls = [self%nulls, (merge(1.0_dp, 0.0_dp, self%nu_kind(k) == NU_SCALE), &
                                       k=1, size(self%nu_kind))]
            allocate (self%row_t0(size(row_exp)), self%row_bias(size(row_exp)), &
                      self%row_scale(size(row_exp)), self%row_v0(size(row_exp)), source=0)
            do k = 1, size(self%nu_kind)
                e = self%nu_exp(k)
                do i = 1, size(row_exp)
                    if (row_exp(i) /= e) cycle
                    select case (self%nu_kind(k))
                    case (NU_T0)
                        self%row_t0(i) = self%np + k
                    case (NU_V0)
                        self%row_v0(i) = self%np + k
                    case (NU_BIAS)
                        if (row_quantity(i) == self%nu_q(k)) self%row_bias(i) = self%np + k
                    case (NU_SCALE)
                        if (row_quantity(i) == self%nu_q(k)) self%row_scale(i) = self%np + k
                    end select
                end do
            end do
        end subroutine chain_init

        !> A family's message names its own row k: name the data row.
        subroutine renumber(rows)
            integer, intent(in) :: rows(:)
            integer :: at, k, ios, rest
            at = index(stat%message, 'row ')
            if (at == 0) return
            rest = verify(stat%message(at + 4:), '0123456789') + at + 3
            read (stat%message(at + 4:rest - 1), *, iostat=ios) k
            if (ios /= 0 .or. k < 1 .or. k > size(rows)) return
            stat%message = stat%message(:at + 3)//fmt_int(rows(k))//stat%message(rest:)
        end subroutine renumber
    end subroutine inverse_problem_init

    !> The nuisance parameters the experiments' specs ask for (keys t0, v0,
    !! bias, scale), in parameter order: per experiment its clock
    !! offset, its biases by entry of the observation list, its scales
    !! likewise. kinds NU_*, exps the experiment, qs the entry (0 for t0).
    !! nobs: the length of the problem's observation list (absent: the kind
    !! codes, NKIND entries). A clock offset on a static experiment, or a flag
    !! or mask out of range, is an input error naming the experiment.
    subroutine chain_layout(exp_kind, specs, kinds, exps, qs, stat, nobs)
        integer, intent(in) :: exp_kind(:)
        type(experiment_spec_t), intent(in) :: specs(:)
        integer, allocatable, intent(out) :: kinds(:), exps(:), qs(:)
        type(status_t), intent(inout) :: stat
        integer, intent(in), optional :: nobs
        character(len=*), parameter :: where = 'measurement chain'
        integer :: e, q, t0, m, n
        integer(int64) :: mask(2)
        allocate (kinds(0), exps(0), qs(0))
        n = size(default_observations())
        if (present(nobs)) n = nobs
        do e = 1, size(exp_kind)
            do m = 1, 2
                associate (v => specs(e)%get(merge(EV_BIAS, EV_SCALE, m == 1)))
                    if (.not. channel_mask_ok(v, n)) then
                        call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                        ': '//trim(merge('bias ', 'scale', m == 1))// &
                                        ' channel mask = '//fmt_real(v)//', expected '// &
                                        channel_mask_range(n))
                        return
                    end if
                end associate
            end do
            mask = nint(specs(e)%get([EV_BIAS, EV_SCALE]), int64)
            t0 = -1
            if (specs(e)%get(EV_T0) == 0.0_dp .or. specs(e)%get(EV_T0) == 1.0_dp) &
                t0 = specs(e)%get_int(EV_T0)
            if (t0 /= 0 .and. t0 /= 1) then
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                ': time offset flag = '//fmt_real(specs(e)%get(EV_T0))// &
                                ', expected 0 or 1')
                return
            end if
            if (t0 == 1 .and. .not. kind_timed(exp_kind(e))) then
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                ': a time offset asked for a static experiment (only a '// &
                                'release has a record in time)')
                return
            end if
            if (t0 == 1) call push(NU_T0, 0)
            associate (v => specs(e)%get(EV_V0))
                if (v /= 0.0_dp .and. v /= 1.0_dp) then
                    call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                    ': initial velocity flag v0 = '//fmt_real(v)// &
                                    ', expected 0 or 1')
                    return
                end if
                if (v == 1.0_dp .and. exp_kind(e) /= EXP_RELEASE) then
                    call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                    ': an initial velocity v0 asked for an experiment '// &
                                    'that is not a release (only a release starts '// &
                                    'moving)')
                    return
                end if
                if (v == 1.0_dp) call push(NU_V0, 0)
            end associate
            do m = 1, 2
                do q = 1, min(n, MAX_CHANNEL_BITS)
                    if (btest(mask(m), q - 1)) call push(NU_BIAS + m - 1, q)
                end do
            end do
        end do
    contains
        subroutine push(kind, q)
            integer, intent(in) :: kind, q
            kinds = [kinds, kind]
            exps = [exps, e]
            qs = [qs, q]
        end subroutine push
    end subroutine chain_layout

    !> A channel mask v is a whole number with bits only for the first
    !! min(nobs, MAX_CHANNEL_BITS) entries of the observation list.
    pure logical function channel_mask_ok(v, nobs)
        real(dp), intent(in) :: v
        integer, intent(in) :: nobs
        channel_mask_ok = v >= 0.0_dp .and. v <= 2.0_dp**min(nobs, MAX_CHANNEL_BITS) - 1.0_dp &
                          .and. v == aint(v)
    end function channel_mask_ok

    !> What channel_mask_ok expects, in words.
    pure function channel_mask_range(nobs) result(text)
        integer, intent(in) :: nobs
        character(len=:), allocatable :: text
        character(len=24) :: buf
        write (buf, '(i0)') 2_int64**min(nobs, MAX_CHANNEL_BITS) - 1_int64
        text = 'an integer in 0..'//trim(buf)//' (bit q - 1 for entry q of the '// &
               fmt_int(nobs)//' observations)'
    end function channel_mask_range

    !> Each family's rows, scattered back in data order, then the
    !! measurement chain: row i reads s h_i(p, t_i + t0) + b, with columns
    !! s dh/dp, s dh/dt (t0), 1 (b) and h (s).
    subroutine inverse_evaluate(self, params, wrt, predictions, jacobian, stat)
        class(inverse_problem_t), intent(inout) :: self
        real(dp), intent(in) :: params(:)
        integer, intent(in) :: wrt(:)
        real(dp), intent(out) :: predictions(:)
        real(dp), intent(out) :: jacobian(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: p(:), j(:, :), scale(:)
        integer, allocatable :: pw(:), pcol(:)
        integer :: np, c, i, k, f
        np = self%np
        predictions = 0.0_dp
        jacobian = 0.0_dp
        if (np == 0) np = size(params)     ! built without inverse_problem_init
        if (allocated(self%nu_kind)) then
            if (size(params) /= np + size(self%nu_kind)) then
                call set_status(stat, ERR_INPUT, 'parameters', fmt_int(size(params))// &
                                ' values, expected '//fmt_int(np)//' model parameters and '// &
                                fmt_int(size(self%nu_kind))//' of the measurement chain')
                return
            end if
        end if
        ! the model's columns asked for, and where they go
        pcol = pack([(c, c=1, size(wrt))], wrt <= np)
        pw = wrt(pcol)
        do f = 1, size(self%fams)
            associate (fam => self%fams(f)%item)
                if (size(fam%rows) == 0) cycle
                allocate (p(size(fam%rows)), j(size(fam%rows), size(pw)))
                fam%rough = self%rough   ! the fit's mode reaches the family
                do k = 1, size(self%nu_kind)
                    if (self%nu_kind(k) /= NU_T0) cycle
                    if (self%exp_fam(self%nu_exp(k)) /= f) cycle
                    fam%shift(self%exp_loc(self%nu_exp(k))) = params(np + k)
                end do
                if (any(self%nu_kind == NU_V0)) then
                    if (.not. allocated(fam%v0)) allocate (fam%v0(size(fam%exp_ids)))
                    if (.not. allocated(fam%v0_fit)) allocate (fam%v0_fit(size(fam%exp_ids)))
                    fam%v0 = 0.0_dp
                    fam%v0_fit = .false.
                    do k = 1, size(self%nu_kind)
                        if (self%nu_kind(k) /= NU_V0) cycle
                        if (self%exp_fam(self%nu_exp(k)) /= f) cycle
                        fam%v0(self%exp_loc(self%nu_exp(k))) = params(np + k)
                        fam%v0_fit(self%exp_loc(self%nu_exp(k))) = any(wrt == np + k)
                    end do
                end if
                call fam%evaluate(params(1:np), pw, p, j, stat)
                if (stat%code /= STATUS_OK) return
                predictions(fam%rows) = p
                jacobian(fam%rows, pcol) = j
                deallocate (p, j)
            end associate
        end do
        if (.not. allocated(self%nu_kind)) return
        if (size(self%nu_kind) == 0) return
        allocate (scale(size(predictions)), source=1.0_dp)
        where (self%row_scale > 0) scale = params(max(self%row_scale, 1))
        do c = 1, size(wrt)
            if (wrt(c) <= np) then
                jacobian(:, c) = scale*jacobian(:, c)
                cycle
            end if
            k = wrt(c) - np
            select case (self%nu_kind(k))
            case (NU_T0)
                do f = 1, size(self%fams)
                    associate (fam => self%fams(f)%item)
                        if (.not. allocated(fam%row_rate)) cycle
                        do i = 1, size(fam%rows)
                            if (self%row_t0(fam%rows(i)) == wrt(c)) jacobian(fam%rows(i), c) = &
                                scale(fam%rows(i))*fam%row_rate(i)
                        end do
                    end associate
                end do
            case (NU_V0)
                do f = 1, size(self%fams)
                    associate (fam => self%fams(f)%item)
                        if (.not. allocated(fam%row_dv0)) cycle
                        do i = 1, size(fam%rows)
                            if (self%row_v0(fam%rows(i)) == wrt(c)) jacobian(fam%rows(i), c) = &
                                scale(fam%rows(i))*fam%row_dv0(i)
                        end do
                    end associate
                end do
            case (NU_BIAS)
                where (self%row_bias == wrt(c)) jacobian(:, c) = 1.0_dp
            case (NU_SCALE)
                where (self%row_scale == wrt(c)) jacobian(:, c) = predictions
            end select
        end do
        predictions = scale*predictions
        where (self%row_bias > 0) predictions = predictions + params(max(self%row_bias, 1))
    end subroutine inverse_evaluate

    !> The least-squares problem of data rows y (sigma) and a priori
    !! information `prior` on this model: within its physical bounds, its
    !! effects switched off at its null values (Eq. 39, 53-55, 142-148).
    pure type(lsq_problem_t) function inverse_lsq(self, y, sigma, prior) result(lp)
        type(inverse_problem_t), intent(in) :: self
        real(dp), intent(in) :: y(:), sigma(:)
        type(prior_t), intent(in) :: prior
        lp = lsq_problem_t(y, sigma, self%lower, self%upper, self%nulls, prior)
    end function inverse_lsq

    !> The experiments' specs from named triples: experiment e of
    !! kind exp_kind(e) takes, for every key of SPEC_KEYS its family
    !! accepts, the value of the triple (kv_exp = e, kv_key = that key's
    !! index, kv_value) or else the key's default (keys it does not accept:
    !! 0). A key its family does not accept, an unknown key or experiment,
    !! or a key given twice is an input error naming the experiment, the key
    !! and the keys accepted.
    subroutine specs_from_triples(exp_kind, kv_exp, kv_key, kv_value, specs, stat)
        integer, intent(in) :: exp_kind(:), kv_exp(:), kv_key(:)
        real(dp), intent(in) :: kv_value(:)
        type(experiment_spec_t), allocatable, intent(out) :: specs(:)
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'experiments'
        type(family_slot_t), allocatable :: reg(:)
        logical, allocatable :: given(:, :)
        integer :: e, i, k, f
        character(len=:), allocatable :: accepted
        allocate (specs(size(exp_kind)))
        allocate (given(size(SPEC_KEYS), size(exp_kind)), source=.false.)
        if (size(kv_key) /= size(kv_exp) .or. size(kv_value) /= size(kv_exp)) then
            call set_status(stat, ERR_INPUT, where, 'spec triples: experiment, key and value '// &
                            'lists differ in length')
            return
        end if
        call registered_families(reg)
        do e = 1, size(exp_kind)
            f = family_of_kind(reg, exp_kind(e))
            if (f == 0) then
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)//' has '// &
                                'kind '//fmt_int(exp_kind(e))//', expected '//kinds_expected())
                return
            end if
            do k = 1, size(SPEC_KEYS)
                if (reg(f)%item%accepts(k)) call specs(e)%set(k, SPEC_KEYS(k)%default)
            end do
        end do
        do i = 1, size(kv_exp)
            e = kv_exp(i)
            if (e < 1 .or. e > size(exp_kind)) then
                call set_status(stat, ERR_INPUT, where, 'spec triple '//fmt_int(i)// &
                                ' names experiment '//fmt_int(e)//', expected 1..'// &
                                fmt_int(size(exp_kind)))
                return
            end if
            k = kv_key(i)
            f = family_of_kind(reg, exp_kind(e))
            if (k >= 1 .and. k <= size(SPEC_KEYS)) then
                if (reg(f)%item%accepts(k)) then
                    if (given(k, e)) then
                        call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                        ': key '//trim(SPEC_KEYS(k)%name)//' given twice')
                        return
                    end if
                    given(k, e) = .true.
                    call specs(e)%set(k, kv_value(i))
                    cycle
                end if
            end if
            accepted = ''
            do k = 1, size(SPEC_KEYS)
                if (.not. reg(f)%item%accepts(k)) cycle
                if (len(accepted) > 0) accepted = accepted//', '
                accepted = accepted//trim(SPEC_KEYS(k)%name)
            end do
            if (kv_key(i) >= 1 .and. kv_key(i) <= size(SPEC_KEYS)) then
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)//' ('// &
                                reg(f)%item%name()//'): key '// &
                                trim(SPEC_KEYS(kv_key(i))%name)//' is not a key of a '// &
                                reg(f)%item%name()//' experiment; expected one of '//accepted)
            else
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)//' ('// &
                                reg(f)%item%name()//'): key number '//fmt_int(kv_key(i))// &
                                ' is unknown; expected one of '//accepted)
            end if
            return
        end do
    end subroutine specs_from_triples

    !> The problem's observation list from parallel arrays (kind code, beam
    !! and arc length s of each entry; beamid_observations).
    pure function observation_list(kind, beam, s) result(obs)
        integer, intent(in) :: kind(:), beam(:)
        real(dp), intent(in) :: s(:)
        type(observation_t) :: obs(size(kind))
        integer :: i
        ! a modal observation's kind carries its mode (MODE_STRIDE)
        obs = [(observation_t(kind=mod(kind(i), MODE_STRIDE), beam=beam(i), s=s(i), &
                              mode=kind(i)/MODE_STRIDE), i=1, size(kind))]
    end function observation_list

    !> The inverse problem of the marshalled arrays of a front: experiments
    !! (kinds, specs), rows (experiment, t, entry of the observation
    !! list) and the observation list as parallel arrays (obs_kind,
    !! obs_beam, obs_s; observation_list).
    subroutine problem_from_arrays(nbeams, exp_kind, specs, row_exp, row_t, row_q, &
                                   obs_kind, obs_beam, obs_s, tol, model, stat, hist)
        integer, intent(in) :: nbeams, exp_kind(:), row_exp(:), row_q(:)
        integer, intent(in) :: obs_kind(:), obs_beam(:)
        type(experiment_spec_t), intent(in) :: specs(:)
        real(dp), intent(in) :: row_t(:), obs_s(:), tol
        type(inverse_problem_t), intent(out) :: model
        type(status_t), intent(inout) :: stat
        !> the release experiments' load histories (their own list)
        type(exp_histories_t), intent(in), optional :: hist
        call inverse_problem_init(nbeams, exp_kind, specs, row_exp, row_t, row_q, tol, &
                                  model, stat, observation_list(obs_kind, obs_beam, obs_s), &
                                  hist=hist)
    end subroutine problem_from_arrays

    !> The inverse problem and its least-squares problem from the
    !! marshalled arrays of a front (the set-up every estimation entry of
    !! the binding shares): problem_from_arrays, then the data rows y
    !! (sigma) with a priori information, columns [index, mean, sigma] of
    !! `prior`, independent (prior_cov empty) or a full covariance of the
    !! prior parameters (prior_cov: nprior**2 values, column by column; a
    !! previous fit carried forward, Eq. 146-148, 164-166).
    subroutine problem_lsq_from_arrays(nbeams, exp_kind, specs, row_exp, row_t, row_q, &
                                       obs_kind, obs_beam, obs_s, tol, y, sigma, prior, &
                                       prior_cov, model, lp, stat, hist)
        integer, intent(in) :: nbeams, exp_kind(:), row_exp(:), row_q(:)
        integer, intent(in) :: obs_kind(:), obs_beam(:)
        type(experiment_spec_t), intent(in) :: specs(:)
        real(dp), intent(in) :: row_t(:), obs_s(:), tol
        real(dp), intent(in) :: y(:), sigma(:), prior(:, :), prior_cov(:)
        type(inverse_problem_t), intent(out) :: model
        type(lsq_problem_t), intent(out) :: lp
        type(status_t), intent(inout) :: stat
        !> the release experiments' load histories (their own list)
        type(exp_histories_t), intent(in), optional :: hist
        type(prior_t) :: pr
        integer :: n
        n = size(prior, 2)
        if (size(prior_cov) /= 0 .and. size(prior_cov) /= n*n) then
            call set_status(stat, ERR_INPUT, 'prior', 'prior_cov has '// &
                            fmt_int(size(prior_cov))//' values, expected nprior**2 = '// &
                            fmt_int(n*n))
            return
        end if
        call problem_from_arrays(nbeams, exp_kind, specs, row_exp, row_t, row_q, &
                                 obs_kind, obs_beam, obs_s, tol, model, stat, hist)
        if (stat%code /= STATUS_OK) return
        ! the prior as a variable of its own: gfortran 12 passed the structure
        ! constructor's allocatable components as freed temporaries (a fit
        ! with a prior of two or more parameters read garbage)
        pr%index = nint(prior(1, :))
        pr%mean = prior(2, :)
        pr%sigma = prior(3, :)
        lp = inverse_lsq(model, y, sigma, pr)
        if (size(prior_cov) /= 0) call prior_from_covariance(nint(prior(1, :)), prior(2, :), &
                                                             reshape(prior_cov, [n, n]), &
                                                             lp%prior, stat)
    end subroutine problem_lsq_from_arrays

    !> Whether the problem has a timed family (records in time: integrated
    !! responses, each evaluation costly).
    logical function problem_timed(self)
        class(inverse_problem_t), intent(in) :: self
        integer :: f
        problem_timed = .false.
        if (.not. allocated(self%fams)) return
        do f = 1, size(self%fams)
            if (self%fams(f)%item%timed()) problem_timed = .true.
        end do
    end function problem_timed

end module beamid_problem
