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
module beamid_inverse
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, STATUS_OK, ERR_INPUT, fmt_int, fmt_real
    use beamid_arclength, only: static_load_t, LOAD_TIP, LOAD_WIRE
    use beamid_estimation, only: residual_model_t, prior_t, lsq_problem_t, fit_options_t, &
                                 fit_result_t, candidate_t, diagnose_options_t, diagnosis_t, &
                                 fit_at, diagnose
    use beamid_static_experiments, only: static_experiments_t, static_experiments_init, &
                                         probe_rows
    use beamid_observations, only: observation_t, obs_label, same_observation, &
                                   default_observations
    use beamid_effects, only: effect_bounds, effect_null_values
    use beamid_dynamic_experiments, only: release_exp_t, dynamic_experiments_t, &
                                          dynamic_experiments_init
    implicit none
    private

    public :: inverse_problem_t, inverse_problem_init, inverse_lsq, inverse_diagnose

    !> Experiment kinds: the static loads of beamid_arclength, and a release.
    integer, parameter, public :: EXP_TIP = LOAD_TIP, EXP_WIRE = LOAD_WIRE, EXP_RELEASE = 3
    !> Rows of an experiment's value column.
    integer, parameter, public :: EV_FX = 1, EV_FY = 2, EV_MOMENT = 3, EV_WIRE_LENGTH = 4, &
                                  EV_NEPB = 5, EV_GAIN = 6, EV_METHOD = 7, EV_LAW = 8, &
                                  EV_RTOL = 9, EV_DT = 10, EV_VSLIP = 11, EV_FD = 12
    !! (EV_FD = 1: central-difference sensitivities, the benchmark baseline;
    !! 2: forward sensitivities at the experiment's tolerance at every fit
    !! iteration, no rough Jacobian: fit(..., jacobian="exact"))
    integer, parameter, public :: NEXPVAL = 12

    type, extends(residual_model_t) :: inverse_problem_t
        integer :: nrow = 0
        logical :: has_static = .false., has_dynamic = .false.
        type(static_experiments_t) :: st
        type(dynamic_experiments_t) :: dy
        integer, allocatable :: st_rows(:), dy_rows(:) !< data rows of each family
        integer, allocatable :: st_exp(:)  !< experiment number of each static experiment
        real(dp) :: tol = 0.0_dp           !< static solver tolerance (0: default)
        type(observation_t), allocatable :: obs(:)  !< the observation of each row
        !> physical bounds and null (switched-off) values of every parameter:
        !! they belong to the model, whatever the experiments
        real(dp), allocatable :: lower(:), upper(:), nulls(:)
    contains
        procedure :: evaluate => inverse_evaluate
    end type inverse_problem_t

contains

    !> Build the problem: a constructor per family (static_experiments_init,
    !! dynamic_experiments_init) on the rows of its experiments.
    !! row_quantity(i) indexes obs, the problem's observation list (absent:
    !! the kind codes, beamid_observations default_observations).
    subroutine inverse_problem_init(nbeams, exp_kind, exp_values, row_exp, row_t, &
                                    row_quantity, tol, self, stat, obs)
        integer, intent(in) :: nbeams
        integer, intent(in) :: exp_kind(:), row_exp(:), row_quantity(:)
        real(dp), intent(in) :: exp_values(:, :), row_t(:), tol
        type(inverse_problem_t), intent(out) :: self
        type(status_t), intent(inout) :: stat
        type(observation_t), intent(in), optional :: obs(:)
        type(observation_t), allocatable :: list(:), robs(:)
        character(len=*), parameter :: where = 'experiments'
        type(static_load_t), allocatable :: loads(:)
        type(release_exp_t), allocatable :: rels(:)
        integer, allocatable :: smap(:), dmap(:)
        integer :: e, i, j, ns, nd
        logical :: dynamic
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
        allocate (smap(size(exp_kind)), dmap(size(exp_kind)), source=0)
        ns = 0
        nd = 0
        allocate (loads(0), rels(0))
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
            case default
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(e)//' has '// &
                                'kind '//fmt_int(exp_kind(e))//', expected 1 (tip load), '// &
                                '2 (wire) or 3 (release)')
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
        call static_experiments_init(nbeams, loads, smap(row_exp(self%st_rows)), &
                                     robs(self%st_rows), tol, self%st, stat)
        if (stat%code /= STATUS_OK) then
            call renumber(self%st_rows)
            return
        end if
        call dynamic_experiments_init(nbeams, rels, dmap(row_exp(self%dy_rows)), &
                                      row_t(self%dy_rows), robs(self%dy_rows), &
                                      self%dy, stat)
        if (stat%code /= STATUS_OK) call renumber(self%dy_rows)
        ! releases on the implicit integrator can steer the fit with rough
        ! sensitivities (beamid_dynamic_experiments, ROUGH_RTOL)
        self%rough_jacobian_ok = self%dy%rough_jacobian_ok
    contains
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

    !> Each family's rows, scattered back in data order.
    subroutine inverse_evaluate(self, params, wrt, predictions, jacobian, stat)
        class(inverse_problem_t), intent(inout) :: self
        real(dp), intent(in) :: params(:)
        integer, intent(in) :: wrt(:)
        real(dp), intent(out) :: predictions(:)
        real(dp), intent(out) :: jacobian(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: p(:), j(:, :)
        predictions = 0.0_dp
        jacobian = 0.0_dp
        if (size(self%st_rows) > 0) then
            allocate (p(size(self%st_rows)), j(size(self%st_rows), size(wrt)))
            call self%st%evaluate(params, wrt, p, j, stat)
            if (stat%code /= STATUS_OK) return
            predictions(self%st_rows) = p
            jacobian(self%st_rows, :) = j
            deallocate (p, j)
        end if
        if (size(self%dy_rows) > 0) then
            allocate (p(size(self%dy_rows)), j(size(self%dy_rows), size(wrt)))
            self%dy%rough = self%rough   ! the fit's mode reaches the releases
            call self%dy%evaluate(params, wrt, p, j, stat)
            if (stat%code /= STATUS_OK) return
            predictions(self%dy_rows) = p
            jacobian(self%dy_rows, :) = j
        end if
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
        integer, allocatable :: plocal(:)
        integer :: i
        allocate (pexp(0), pq(0))
        call fit_at(self, lp, params0, free, fopts, base, stat)
        if (stat%code /= STATUS_OK) return
        if (self%has_static) then
            call probe_rows(self%st%loads, self%st%row_obs%kind, lp%sigma(self%st_rows), &
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
