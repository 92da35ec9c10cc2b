!> One inverse problem from any mix of experiment families (issue 13).
!!
!! `inverse_problem_t` is a `residual_model_t` whose data rows belong to
!! static experiments (beamid_static_experiments: the arc-length solver,
!! Eq. 40-56) or to release experiments (beamid_dynamic_experiments: the
!! finite element dynamics, Eq. 107, 135-140, 159-162); `evaluate` asks each
!! family for its rows and scatters them back in data order, so
!! `fit_least_squares`, `score_test` and `diagnose` serve both, alone or
!! mixed (the three stages of Chapter VI in one fit if wanted).
!!
!! Experiments cross as a kind (EXP_TIP, EXP_WIRE, EXP_RELEASE) and a
!! column of NEXPVAL values (layout EV_*); rows as (experiment, t,
!! observation), the observation an index into the problem's observation
!! list (beamid_observations: a kind and its locus; without a list, the
!! index is the kind code). Static rows need t = 0; duplicate (experiment,
!! t, observation) rows are rejected, naming the row.
!!
!! The measurement chain (issue 29): an experiment's value column may ask
!! for nuisance parameters, fitted with the physics as extra columns: a
!! clock offset t0 of a release's record (EV_T0 = 1: row i is the model at
!! time t_i + t0, so t0 is the model time at the record's zero; column
!! s h'(t_i + t0), the observation's rate from the integrated state; the
!! accelerations have none, and a time offset on a record with such rows is
!! an input error), and per channel (experiment, observation) a bias b and a
!! scale s (bit q - 1 of EV_BIAS, EV_SCALE for entry q of the observation
!! list, so without a list for kind code q: the row reads s h + b; columns 1
!! and h). They follow the model's parameters in the parameter vector, in
!! the order of chain_layout: per experiment its t0, its biases by entry of
!! the observation list, its scales likewise. Null values t0 = 0, b = 0,
!! s = 1 (the perfect chain), so the score test and refits of
!! beamid_estimation treat them as effects.
module beamid_inverse
    use, intrinsic :: iso_fortran_env, only: int64
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, STATUS_OK, ERR_INPUT, fmt_int, fmt_real
    use beamid_arclength, only: static_load_t, LOAD_TIP, LOAD_WIRE
    use beamid_estimation, only: residual_model_t, prior_t, lsq_problem_t, fit_options_t, &
                                 fit_result_t, candidate_t, diagnose_options_t, diagnosis_t, &
                                 fit_at, diagnose
    use beamid_static_experiments, only: static_experiments_t, static_experiments_init, &
                                         probe_rows
    use beamid_observations, only: observation_t, obs_label, same_observation, &
                                   default_observations, K_ACCEL_T, K_ACCEL_N
    use beamid_effects, only: effect_bounds, effect_null_values
    use beamid_dynamic_experiments, only: release_exp_t, dynamic_experiments_t, &
                                          dynamic_experiments_init
    use beamid_modal_experiments, only: modal_exp_t, modal_experiments_t, &
                                        modal_experiments_init
    use beamid_chain_fit, only: chain_rows_t
    implicit none
    private

    public :: inverse_problem_t, inverse_problem_init, inverse_lsq, inverse_diagnose
    public :: chain_layout

    !> Experiment kinds: the static loads of beamid_arclength, and a release.
    integer, parameter, public :: EXP_TIP = LOAD_TIP, EXP_WIRE = LOAD_WIRE, EXP_RELEASE = 3
    !> A modal test about the equilibrium under the load (EV_FX, EV_FY,
    !! EV_MOMENT, exact moment form; mesh EV_NEPB): beamid_modal_experiments,
    !! the third family, in the style of the other two (issue 27).
    integer, parameter, public :: EXP_MODAL = 4
    !> Rows of an experiment's value column.
    integer, parameter, public :: EV_FX = 1, EV_FY = 2, EV_MOMENT = 3, EV_WIRE_LENGTH = 4, &
                                  EV_NEPB = 5, EV_GAIN = 6, EV_METHOD = 7, EV_LAW = 8, &
                                  EV_RTOL = 9, EV_DT = 10, EV_VSLIP = 11, EV_FD = 12
    !! (EV_FD = 1: central-difference sensitivities, the benchmark baseline;
    !! 2: forward sensitivities at the experiment's tolerance at every fit
    !! iteration, no rough Jacobian: fit(..., jacobian="exact"))
    !> The measurement chain of an experiment: EV_T0 (1: its record has a
    !! clock offset, releases only), EV_BIAS and EV_SCALE (bit q - 1 set: the
    !! channel of entry q of the observation list has a bias, a scale).
    integer, parameter, public :: EV_T0 = 13, EV_BIAS = 14, EV_SCALE = 15
    !> The rows' treatment (beamid_chain_fit): EV_LOSS the loss of the
    !! experiment's rows (0 linear, 1 Huber, 2 Cauchy), EV_BURNIN a time
    !! before which its rows are predicted but not fitted (0: none), EV_SIGEST
    !! the channels (bit q - 1: entry q of the observation list) whose sigma
    !! is estimated from the residuals.
    integer, parameter, public :: EV_LOSS = 16, EV_BURNIN = 17, EV_SIGEST = 18
    integer, parameter, public :: NEXPVAL = 18
    !> Kinds of the nuisance parameters (chain_layout).
    integer, parameter, public :: NU_T0 = 1, NU_BIAS = 2, NU_SCALE = 3
    !> A channel mask is a whole number in a double: bits for the first 52
    !! entries of the observation list at most.
    integer, parameter, public :: MAX_CHANNEL_BITS = 52

    type, extends(residual_model_t) :: inverse_problem_t
        integer :: nrow = 0
        logical :: has_static = .false., has_dynamic = .false., has_modal = .false.
        type(static_experiments_t) :: st
        type(dynamic_experiments_t) :: dy
        type(modal_experiments_t) :: mo
        integer, allocatable :: st_rows(:), dy_rows(:) !< data rows of each family
        integer, allocatable :: mo_rows(:)
        integer, allocatable :: st_exp(:)  !< experiment number of each static experiment
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
        integer, allocatable :: dy_exp(:) !< release number of each experiment (0: static)
        type(chain_rows_t) :: rows        !< each row's loss, burn-in, estimated sigma
    contains
        procedure :: evaluate => inverse_evaluate
    end type inverse_problem_t

contains

    !> Build the problem: a constructor per family (static_experiments_init,
    !! dynamic_experiments_init) on the rows of its experiments.
    !! row_quantity(i) indexes obs, the problem's observation list (absent:
    !! the kind codes, beamid_observations default_observations).
    !! probe = .true.: rows that only predict (a diagnosis's probe rows on
    !! the data problem's experiments and chain): a channel of the chain or
    !! of an estimated sigma need not have rows among them.
    subroutine inverse_problem_init(nbeams, exp_kind, exp_values, row_exp, row_t, &
                                    row_quantity, tol, self, stat, obs, probe)
        integer, intent(in) :: nbeams
        integer, intent(in) :: exp_kind(:), row_exp(:), row_quantity(:)
        real(dp), intent(in) :: exp_values(:, :), row_t(:), tol
        type(inverse_problem_t), intent(out) :: self
        type(status_t), intent(inout) :: stat
        type(observation_t), intent(in), optional :: obs(:)
        logical, intent(in), optional :: probe
        type(observation_t), allocatable :: list(:), robs(:)
        character(len=*), parameter :: where = 'experiments'
        type(static_load_t), allocatable :: loads(:)
        type(release_exp_t), allocatable :: rels(:)
        type(modal_exp_t), allocatable :: mods(:)
        integer, allocatable :: smap(:), dmap(:), mmap(:)
        integer :: e, i, j, ns, nd, nm
        logical :: dynamic, probing
        if (size(exp_values, 1) /= NEXPVAL .or. size(exp_values, 2) /= size(exp_kind)) then
            call set_status(stat, ERR_INPUT, where, 'experiment values are '// &
                            fmt_int(size(exp_values, 1))//' x '//fmt_int(size(exp_values, 2))// &
                            ', expected '//fmt_int(NEXPVAL)//' x '//fmt_int(size(exp_kind)))
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
        allocate (smap(size(exp_kind)), dmap(size(exp_kind)), mmap(size(exp_kind)), source=0)
        ns = 0
        nd = 0
        nm = 0
        allocate (loads(0), rels(0), mods(0))
        do e = 1, size(exp_kind)
            select case (exp_kind(e))
            case (EXP_TIP, EXP_WIRE)
                ns = ns + 1
                smap(e) = ns
                loads = [loads, static_load_t(kind=exp_kind(e), fx=exp_values(EV_FX, e), &
                                              fy=exp_values(EV_FY, e), &
                                              moment=exp_values(EV_MOMENT, e), &
                                              wire_length=exp_values(EV_WIRE_LENGTH, e))]
            case (EXP_RELEASE)
                nd = nd + 1
                dmap(e) = nd
                rels = [rels, release_exp_t(fx=exp_values(EV_FX, e), fy=exp_values(EV_FY, e), &
                                            moment=exp_values(EV_MOMENT, e), &
                                            nepb=nint(exp_values(EV_NEPB, e)), &
                                            gain=exp_values(EV_GAIN, e), &
                                            method=nint(exp_values(EV_METHOD, e)), &
                                            law=nint(exp_values(EV_LAW, e)), &
                                            rtol=exp_values(EV_RTOL, e), &
                                            dt=exp_values(EV_DT, e), &
                                            vslip=merge(exp_values(EV_VSLIP, e), 1.0e-4_dp, &
                                                        exp_values(EV_VSLIP, e) > 0.0_dp), &
                                            fd=nint(exp_values(EV_FD, e)) == 1, &
                                            exact=nint(exp_values(EV_FD, e)) == 2)]
            case (EXP_MODAL)
                nm = nm + 1
                mmap(e) = nm
                mods = [mods, modal_exp_t(fx=exp_values(EV_FX, e), fy=exp_values(EV_FY, e), &
                                          moment=exp_values(EV_MOMENT, e), &
                                          nepb=nint(exp_values(EV_NEPB, e)), &
                                          fd=nint(exp_values(EV_FD, e)) == 1)]
            case default
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)//' has '// &
                                'kind '//fmt_int(exp_kind(e))//', expected 1 (tip load), '// &
                                '2 (wire), 3 (release) or 4 (modal)')
                return
            end select
        end do
        do i = 1, size(row_exp)
            if (row_exp(i) < 1 .or. row_exp(i) > size(exp_kind)) then
                call set_status(stat, ERR_INPUT, where, 'row '//fmt_int(i)//' names '// &
                                'experiment '//fmt_int(row_exp(i))//', expected 1..'// &
                                fmt_int(size(exp_kind)))
                return
            end if
            dynamic = exp_kind(row_exp(i)) == EXP_RELEASE
            if (exp_kind(row_exp(i)) == EXP_MODAL .and. row_t(i) /= 0.0_dp) then
                call set_status(stat, ERR_INPUT, where, 'row '//fmt_int(i)//': field t = '// &
                                fmt_real(row_t(i))//', expected 0 for the modal experiment '// &
                                fmt_int(row_exp(i)))
                return
            end if
            if (.not. dynamic .and. row_t(i) /= 0.0_dp) then
                call set_status(stat, ERR_INPUT, where, 'row '//fmt_int(i)//': field t = '// &
                                fmt_real(row_t(i))//', expected 0 for the static experiment '// &
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
        self%st_rows = pack([(i, i=1, size(row_exp))], smap(row_exp) > 0)
        self%dy_rows = pack([(i, i=1, size(row_exp))], dmap(row_exp) > 0)
        self%mo_rows = pack([(i, i=1, size(row_exp))], mmap(row_exp) > 0)
        self%has_modal = nm > 0
        self%has_static = ns > 0
        self%has_dynamic = nd > 0
        ! a release's predictions do not depend on the sensitivities asked,
        ! which cost several runs: the fit judges its trial steps without them
        self%plain_trials = nd > 0
        self%st_exp = pack([(e, e=1, size(exp_kind))], smap > 0)
        self%tol = tol
        self%obs = robs
        call effect_bounds(nbeams, self%lower, self%upper)
        call effect_null_values(nbeams, self%nulls)
        call chain_init(stat)
        if (stat%code /= STATUS_OK) return
        call rows_init(stat)
        if (stat%code /= STATUS_OK) return
        call static_experiments_init(nbeams, loads, smap(row_exp(self%st_rows)), &
                                     robs(self%st_rows), tol, self%st, stat)
        if (stat%code /= STATUS_OK) then
            call renumber(self%st_rows)
            return
        end if
        call dynamic_experiments_init(nbeams, rels, dmap(row_exp(self%dy_rows)), &
                                      row_t(self%dy_rows), robs(self%dy_rows), &
                                      self%dy, stat)
        if (stat%code /= STATUS_OK) then
            call renumber(self%dy_rows)
            return
        end if
        call modal_experiments_init(nbeams, mods, mmap(row_exp(self%mo_rows)), &
                                    row_t(self%mo_rows), robs(self%mo_rows), self%mo, stat)
        if (stat%code /= STATUS_OK) call renumber(self%mo_rows)
        ! releases on the implicit integrator can steer the fit with rough
        ! sensitivities (beamid_dynamic_experiments, ROUGH_RTOL)
        self%rough_jacobian_ok = self%dy%rough_jacobian_ok
        self%dy%want_rates = any(self%nu_kind == NU_T0)
        self%dy_exp = dmap
    contains
        !> Each row's loss, burn-in and estimated sigma (EV_LOSS, EV_BURNIN,
        !! EV_SIGEST), checked: a loss code 0..2, a burn-in time >= 0 on a
        !! release only, a channel mask whose channels have rows.
        subroutine rows_init(stat)
            type(status_t), intent(inout) :: stat
            integer :: e, q, nchan, i
            real(dp) :: v
            integer(int64) :: mask
            allocate (self%rows%loss(size(row_exp)), self%rows%channel(size(row_exp)), source=0)
            allocate (self%rows%fitted(size(row_exp)), source=.true.)
            if (size(exp_values, 1) < NEXPVAL) return
            nchan = 0
            do e = 1, size(exp_kind)
                v = exp_values(EV_LOSS, e)
                if (.not. (v == 0.0_dp .or. v == 1.0_dp .or. v == 2.0_dp)) then
                    call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                    ': loss code = '//fmt_real(v)//', expected 0 (linear), '// &
                                    '1 (huber) or 2 (cauchy)')
                    return
                end if
                v = exp_values(EV_BURNIN, e)
                if (.not. (v >= 0.0_dp .and. v < huge(1.0_dp))) then
                    call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                    ': burn-in = '//fmt_real(v)//', expected a time >= 0')
                    return
                end if
                if (v > 0.0_dp .and. exp_kind(e) /= EXP_RELEASE) then
                    call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                    ': a burn-in asked for a static experiment (only a '// &
                                    'release has a record in time)')
                    return
                end if
                v = exp_values(EV_SIGEST, e)
                if (.not. channel_mask_ok(v, size(list))) then
                    call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                    ': sigma channel mask = '//fmt_real(v)//', expected '// &
                                    channel_mask_range(size(list)))
                    return
                end if
                where (row_exp == e) self%rows%loss = nint(exp_values(EV_LOSS, e))
                where (row_exp == e .and. row_t < exp_values(EV_BURNIN, e)) &
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
            call chain_layout(exp_kind, exp_values, self%nu_kind, self%nu_exp, self%nu_q, stat, &
                              size(list))
            if (stat%code /= STATUS_OK) return
            do k = 1, size(self%nu_kind)
                if (self%nu_kind(k) == NU_T0) then
                    ! the t0 column is the rows' time derivative: refuse a
                    ! record whose rows include an observation without one
                    do i = 1, size(row_exp)
                        if (row_exp(i) /= self%nu_exp(k)) cycle
                        if (robs(i)%kind /= K_ACCEL_T .and. robs(i)%kind /= K_ACCEL_N) cycle
                        call set_status(stat, ERR_INPUT, where, 'experiment '// &
                                        fmt_int(self%nu_exp(k))//': a time offset asked, '// &
                                        'but row '//fmt_int(i)//' observes '// &
                                        obs_label(robs(i))//', whose rate (the jerk) the '// &
                                        'fit does not compute yet; expected no time offset '// &
                                        'on a record with acceleration rows')
                        return
                    end do
                    cycle
                end if
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
                      self%row_scale(size(row_exp)), source=0)
            do k = 1, size(self%nu_kind)
                e = self%nu_exp(k)
                do i = 1, size(row_exp)
                    if (row_exp(i) /= e) cycle
                    select case (self%nu_kind(k))
                    case (NU_T0)
                        self%row_t0(i) = self%np + k
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

    !> The nuisance parameters the experiments' value columns ask for (EV_T0,
    !! EV_BIAS, EV_SCALE), in parameter order: per experiment its clock
    !! offset, its biases by entry of the observation list, its scales
    !! likewise. kinds NU_*, exps the experiment, qs the entry (0 for t0).
    !! nobs: the length of the problem's observation list (absent: the kind
    !! codes, NKIND entries). A clock offset on a static experiment, or a flag
    !! or mask out of range, is an input error naming the experiment.
    subroutine chain_layout(exp_kind, exp_values, kinds, exps, qs, stat, nobs)
        integer, intent(in) :: exp_kind(:)
        real(dp), intent(in) :: exp_values(:, :)
        integer, allocatable, intent(out) :: kinds(:), exps(:), qs(:)
        type(status_t), intent(inout) :: stat
        integer, intent(in), optional :: nobs
        character(len=*), parameter :: where = 'measurement chain'
        integer :: e, q, t0, m, n
        integer(int64) :: mask(2)
        allocate (kinds(0), exps(0), qs(0))
        if (size(exp_values, 1) < NEXPVAL) return
        n = size(default_observations())
        if (present(nobs)) n = nobs
        do e = 1, size(exp_kind)
            do m = 1, 2
                associate (v => exp_values(EV_BIAS + m - 1, e))
                    if (.not. channel_mask_ok(v, n)) then
                        call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                        ': '//trim(merge('bias ', 'scale', m == 1))// &
                                        ' channel mask = '//fmt_real(v)//', expected '// &
                                        channel_mask_range(n))
                        return
                    end if
                end associate
            end do
            mask = nint(exp_values([EV_BIAS, EV_SCALE], e), int64)
            t0 = -1
            if (exp_values(EV_T0, e) == 0.0_dp .or. exp_values(EV_T0, e) == 1.0_dp) &
                t0 = nint(exp_values(EV_T0, e))
            if (t0 /= 0 .and. t0 /= 1) then
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                ': time offset flag = '//fmt_real(exp_values(EV_T0, e))// &
                                ', expected 0 or 1')
                return
            end if
            if (t0 == 1 .and. exp_kind(e) /= EXP_RELEASE) then
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)// &
                                ': a time offset asked for a static experiment (only a '// &
                                'release has a record in time)')
                return
            end if
            if (t0 == 1) call push(NU_T0, 0)
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
        integer :: np, c, i, k
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
        if (size(self%st_rows) > 0) then
            allocate (p(size(self%st_rows)), j(size(self%st_rows), size(pw)))
            call self%st%evaluate(params(1:np), pw, p, j, stat)
            if (stat%code /= STATUS_OK) return
            predictions(self%st_rows) = p
            jacobian(self%st_rows, pcol) = j
            deallocate (p, j)
        end if
        if (size(self%dy_rows) > 0) then
            allocate (p(size(self%dy_rows)), j(size(self%dy_rows), size(pw)))
            self%dy%rough = self%rough   ! the fit's mode reaches the releases
            do k = 1, size(self%nu_kind)
                if (self%nu_kind(k) == NU_T0) self%dy%shift(self%dy_exp(self%nu_exp(k))) = &
                    params(np + k)
            end do
            call self%dy%evaluate(params(1:np), pw, p, j, stat)
            if (stat%code /= STATUS_OK) return
            predictions(self%dy_rows) = p
            jacobian(self%dy_rows, pcol) = j
            deallocate (p, j)
        end if
        if (size(self%mo_rows) > 0) then
            allocate (p(size(self%mo_rows)), j(size(self%mo_rows), size(pw)))
            call self%mo%evaluate(params(1:np), pw, p, j, stat)
            if (stat%code /= STATUS_OK) return
            predictions(self%mo_rows) = p
            jacobian(self%mo_rows, pcol) = j
        end if
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
                do i = 1, size(self%dy_rows)
                    if (self%row_t0(self%dy_rows(i)) == wrt(c)) jacobian(self%dy_rows(i), c) = &
                        scale(self%dy_rows(i))*self%dy%row_rate(i)
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

    !> The diagnosis of a fitted model (the orchestration both fronts call):
    !! the base fit evaluated at params0 (the estimates, not refitted), score
    !! tests of every candidate, refits of the leading ones from the
    !! first-order estimate, from params0 with the effect at null, from
    !! `nominal` (the user's starting model) and by continuation, and the
    !! probe rows that separate rivals: every static experiment and every
    !! quantity it can measure (probe_rows). pexp, pq: experiment number and
    !! quantity of each probe row (diag%cand(c)%separating_row indexes them).
    subroutine inverse_diagnose(self, lp, params0, nominal, free, cands, fopts, dopts, base, &
                                diag, pexp, pq, stat)
        type(inverse_problem_t), intent(inout) :: self
        type(lsq_problem_t), intent(in) :: lp
        real(dp), intent(in) :: params0(:), nominal(:)
        integer, intent(in) :: free(:)
        type(candidate_t), intent(in) :: cands(:)
        type(fit_options_t), intent(in) :: fopts
        type(diagnose_options_t), intent(in) :: dopts
        type(fit_result_t), intent(out) :: base
        type(diagnosis_t), intent(out) :: diag
        integer, allocatable, intent(out) :: pexp(:), pq(:)
        type(status_t), intent(inout) :: stat
        type(static_experiments_t) :: probe
        real(dp), allocatable :: psig(:)
        integer, allocatable :: plocal(:), row_kinds(:)
        integer :: i
        allocate (pexp(0), pq(0))
        call fit_at(self, lp, params0, free, fopts, base, stat)
        if (stat%code /= STATUS_OK) return
        if (self%has_static) then
            ! the rows' kinds as a contiguous copy (a component of an array of
            ! types is strided: passing it made an array temporary each call)
            row_kinds = self%st%row_obs%kind
            call probe_rows(self%st%loads, row_kinds, lp%sigma(self%st_rows), &
                            plocal, pq, psig)
            call static_experiments_init(self%st%nbeams, self%st%loads, plocal, &
                                         [(observation_t(kind=pq(i)), i=1, size(pq))], &
                                         self%tol, probe, stat)
            if (stat%code /= STATUS_OK) return
            pexp = self%st_exp(plocal)
            call diagnose(self, lp, base, cands, fopts, dopts, diag, stat, probe, psig, nominal)
        else
            call diagnose(self, lp, base, cands, fopts, dopts, diag, stat, nominal=nominal)
        end if
    end subroutine inverse_diagnose
end module beamid_inverse
