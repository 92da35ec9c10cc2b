!> Dynamic experiments for the estimation machinery (Chapter IV.2, V.2).
!!
!! A release experiment holds the finite element model in static equilibrium
!! under a fixed-direction tip load (same mesh), releases it at rest at t = 0
!! and integrates M q'' + NLT(q) = Q(q, q') (Eq. 107), with the tip motor of
!! Eq. 159 when its gain is positive. A data row is (experiment, t, quantity,
!! value, sigma); t = 0 measures the static shape before the release.
!!
!! Observations come from the one table of beamid_observations (u_tip w_tip
!! x_tip y_tip tip_angle x_elbow y_elbow, plus motor_torque, which only a
!! release with a motor produces; wire_force is static only); each row
!! holds its observation and `observe` computes it and its sensitivities
!! from a release's response.
!!
!! The sensitivity columns (Eq. 135-140, 161-162) are the hand-coded forward
!! sensitivities of beamid_release (release_response: the released shape by
!! the implicit function theorem, the staggered direct method in Radau, the
!! variational equations in RK4, jump conditions at friction switches). A
!! release with `fd` set gets them by central differences of whole runs
!! instead (steps 1e-4 of the parameter's scale): the baseline of the
!! benchmark (benchmarks/bench_dynfit.py), not for fits.
!!
!! Rough answers (residual_model_t%rough, set by the fit while it iterates;
!! docs/workflow.md "How the fit uses the Jacobian"), for a release on the
!! implicit integrator whose own tolerance is tighter than ROUGH_RTOL: with
!! ROUGH_ALL (the search's first phase) its predictions and sensitivities
!! come from runs at ROUGH_RTOL; with ROUGH_JACOBIAN it predicts its rows
!! from a plain run at its own tolerance (the last plain run is cached per
!! experiment, so the plain run that judged an accepted trial step is
!! reused) and takes its sensitivities from a sensitivity run at ROUGH_RTOL.
!! RK4 releases (fixed dt), central-difference ones and those marked
!! `exact` ignore rough mode.
module beamid_dynamic_experiments
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, STATUS_OK, ERR_INPUT, fmt_int, fmt_real
    use beamid_model, only: chain_t, chain_from_vector
    use beamid_fe_assembly, only: fe_load_t
    use beamid_fe_static, only: fe_newton_opts_t, fe_solve_info_t, fe_solve_static
    use beamid_dynamics, only: dyn_system_t, dyn_setup, dyn_tip, FRICTION_SIGN
    use beamid_integrators, only: integ_opts_t, integ_stats_t, history_t, integrate, &
                                  METHOD_IMPLICIT, METHOD_RK4
    use beamid_estimation, only: residual_model_t, ROUGH_JACOBIAN, ROUGH_ALL
    use beamid_release, only: release_spec_t, release_out_t, &
                              sens_response => release_response, QTY_U_TIP, QTY_W_TIP, &
                              QTY_X_TIP, QTY_Y_TIP, QTY_TIP_ANGLE, QTY_X_ELBOW, QTY_Y_ELBOW, &
                              QTY_MOTOR_TORQUE, NQTY
    use beamid_static_experiments, only: distinct_sorted
    use beamid_observations, only: observation_t, observation_why_not, same_observation, &
                                   FAM_RELEASE, why_detail, WHY_OK, WHY_WIRE, WHY_MOTOR, WHY_FAMILY, &
                                   K_X_TIP, K_Y_TIP, K_TIP_ANGLE, K_X_ELBOW, K_Y_ELBOW, K_U_TIP, &
                                   K_W_TIP, K_MOTOR_TORQUE, kind_label
    implicit none
    private

    public :: release_exp_t, dynamic_experiments_t, dynamic_experiments_init
    public :: release_response, check_dynamic_row, observe

    !> One release experiment: load, mesh, motor and integrator controls
    !! (0 for rtol, dt: the integrator's defaults).
    type :: release_exp_t
        real(dp) :: fx = 0.0_dp, fy = 0.0_dp, moment = 0.0_dp
        integer :: nepb = 4
        real(dp) :: gain = 0.0_dp
        integer :: method = METHOD_IMPLICIT
        integer :: law = FRICTION_SIGN
        real(dp) :: rtol = 0.0_dp, dt = 0.0_dp
        real(dp) :: vslip = 1.0e-4_dp
        logical :: fd = .false.   !< central-difference columns (benchmark baseline)
        !> sensitivities at the experiment's own tolerance at every fit
        !! iteration (no rough Jacobian: fit(..., jacobian="exact"))
        logical :: exact = .false.
    end type release_exp_t

    !> Relative (and absolute) integration tolerance of the rough
    !! answers. On the Table 16 release (4 elements per beam, 19
    !! outputs over 0.65 s) the sensitivities' relative error against rtol
    !! 1e-11 is 1e-3 at rtol 1e-9 (5482 steps, 336 ms), 2e-2 at 1e-7 (123
    !! ms), 3.4e-2 at 1e-6 (275 steps, 18 ms) and 3.6e-2 at 1e-5 (12 ms):
    !! 1e-6 is where the cost levels off while the columns stay within a few
    !! per cent, which only slows Gauss-Newton's convergence factor by about
    !! that much (an inexact-Jacobian Newton method converges linearly at the
    !! rate of the Jacobian's relative error). The predictions there are
    !! within 4.4e-3 of the data's sigmas of those at 1e-9 (rtol 1e-11 as
    !! the reference; 2.5e-5 at 1e-9), so the rough model's minimum is within
    !! a few hundredths of a sigma of the accurate one, inside the fit's noise
    !! floor (0.1 sigma), at a twentieth of the cost of a run (7 ms, 1e-9: 135 ms).
    real(dp), parameter :: ROUGH_RTOL = 1.0e-6_dp

    !> The last plain run of an experiment: its parameters and response.
    type :: plain_cache_t
        logical :: valid = .false.
        real(dp), allocatable :: params(:)
        real(dp), allocatable :: y(:, :)
    end type plain_cache_t

    !> A list of observations.
    type :: obs_list_t
        type(observation_t), allocatable :: o(:)
    end type obs_list_t

    !> Release experiments and the data rows they predict.
    type, extends(residual_model_t) :: dynamic_experiments_t
        integer :: nbeams = 0
        type(release_exp_t), allocatable :: exps(:)
        integer, allocatable :: row_exp(:)
        type(observation_t), allocatable :: row_obs(:) !< observation of each row
        !> the distinct observations of each experiment's rows, and the
        !! index of each row's observation in its experiment's list
        type(obs_list_t), allocatable :: eobs(:)
        integer, allocatable :: row_oi(:)
        real(dp), allocatable :: row_t(:)
        type(plain_cache_t), allocatable :: cache(:) !< per experiment (rough mode)
    contains
        procedure :: evaluate => dynamic_evaluate
    end type dynamic_experiments_t

contains

    !> Why a row (t, observation) cannot belong to release experiment `x`
    !! ('' when it can): t negative or not finite, an observation a release
    !! cannot make (wire_force), motor_torque without a motor, a station off
    !! the chain.
    pure function check_dynamic_row(x, t, o, nbeams) result(why)
        type(release_exp_t), intent(in) :: x
        real(dp), intent(in) :: t
        type(observation_t), intent(in) :: o
        integer, intent(in) :: nbeams
        character(len=:), allocatable :: why
        character(len=:), allocatable :: detail
        integer :: reason
        why = ''
        if (.not. ieee_is_finite(t)) then
            why = 'field t is not finite'
        else if (t < 0.0_dp) then
            why = 'field t = '//fmt_real(t)//', expected t >= 0 (0: the static shape '// &
                  'before the release)'
        else
            reason = observation_why_not(o, FAM_RELEASE, .false., x%gain > 0.0_dp, nbeams, &
                                         [real(dp) ::])
            detail = why_detail(o, reason, FAM_RELEASE, nbeams, [real(dp) ::])
            select case (reason)
            case (WHY_OK)
            case (WHY_WIRE)
                why = "field quantity = '"//kind_label(o%kind)//"', but a release experiment "// &
                      'has no wire'
            case (WHY_MOTOR)
                why = "field quantity = '"//kind_label(o%kind)//"', but the experiment has no "// &
                      'motor (motor_gain = 0)'
            case default
                why = "field quantity = '"//kind_label(o%kind)//"': "//detail
            end select
        end if
    end function check_dynamic_row

    !> Set up and validate the experiments and rows (the list lengths and
    !! experiment numbers as inverse_problem_init checked them).
    subroutine dynamic_experiments_init(nbeams, exps, row_exp, row_t, row_obs, self, stat)
        integer, intent(in) :: nbeams
        type(release_exp_t), intent(in) :: exps(:)
        integer, intent(in) :: row_exp(:)
        type(observation_t), intent(in) :: row_obs(:)
        real(dp), intent(in) :: row_t(:)
        type(dynamic_experiments_t), intent(out) :: self
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'dynamic experiments'
        character(len=:), allocatable :: why
        integer :: i, e
        do i = 1, size(exps)
            if (exps(i)%nepb < 1) then
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(i)// &
                                ': elements_per_beam = '//fmt_int(exps(i)%nepb)// &
                                ', expected >= 1')
                return
            end if
            if (.not. (exps(i)%gain >= 0.0_dp .and. ieee_is_finite(exps(i)%gain))) then
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(i)// &
                                ': motor_gain = '//fmt_real(exps(i)%gain)//', expected >= 0')
                return
            end if
        end do
        do i = 1, size(row_exp)
            why = check_dynamic_row(exps(row_exp(i)), row_t(i), row_obs(i), nbeams)
            if (len(why) > 0) then
                call set_status(stat, ERR_INPUT, where, 'row '//fmt_int(i)//': '//why)
                return
            end if
        end do
        self%nbeams = nbeams
        self%exps = exps
        self%row_exp = row_exp
        self%row_t = row_t
        self%row_obs = row_obs
        allocate (self%eobs(size(exps)), self%row_oi(size(row_exp)))
        do i = 1, size(exps)
            allocate (self%eobs(i)%o(0))
        end do
        do i = 1, size(row_exp)
            e = row_exp(i)
            self%row_oi(i) = 0
            if (size(self%eobs(e)%o) > 0) &
                self%row_oi(i) = findloc(same_observation(self%eobs(e)%o, row_obs(i)), .true., 1)
            if (self%row_oi(i) == 0) then
                self%eobs(e)%o = [self%eobs(e)%o, row_obs(i)]
                self%row_oi(i) = size(self%eobs(e)%o)
            end if
        end do
        allocate (self%cache(size(exps)))
        self%rough_jacobian_ok = .false.
        do i = 1, size(exps)
            if (.not. any(row_exp == i)) cycle
            if (rough_tolerance(exps(i)) > 0.0_dp) self%rough_jacobian_ok = .true.
        end do
    end subroutine dynamic_experiments_init

    !> The looser tolerance of x's rough sensitivities, 0 when x has none:
    !! RK4 (fixed dt), central differences, `exact`, or a tolerance of its own
    !! already at ROUGH_RTOL or looser.
    pure real(dp) function rough_tolerance(x)
        type(release_exp_t), intent(in) :: x
        type(integ_opts_t) :: defaults
        real(dp) :: own
        rough_tolerance = 0.0_dp
        if (x%method /= METHOD_IMPLICIT .or. x%fd .or. x%exact) return
        own = defaults%rtol
        if (x%rtol > 0.0_dp) own = x%rtol
        if (own < ROUGH_RTOL) rough_tolerance = ROUGH_RTOL
    end function rough_tolerance

    !> The response of one release at the ascending times t_out: y(i, k)
    !! for every observation obs(i) and dy(i, k, j) = d y(i, k) / d
    !! params(wrt(j)), from the forward sensitivities of beamid_release (or
    !! central differences when x%fd).
    subroutine release_response(nbeams, params, x, t_out, wrt, obs, y, dy, stat)
        integer, intent(in) :: nbeams
        real(dp), intent(in) :: params(:)
        type(release_exp_t), intent(in) :: x
        real(dp), intent(in) :: t_out(:)
        integer, intent(in) :: wrt(:)
        type(observation_t), intent(in) :: obs(:)
        real(dp), intent(out) :: y(:, :), dy(:, :, :)
        type(status_t), intent(inout) :: stat
        type(chain_t) :: chain
        type(release_out_t) :: out
        integer :: i, k
        if (x%fd) then
            call central_differences()
            return
        end if
        y = 0.0_dp
        dy = 0.0_dp
        call chain_from_vector(nbeams, params, chain, stat)
        if (stat%code /= STATUS_OK) return
        call sens_response(chain, release_spec_t(elements_per_beam=x%nepb, load=fe_load_t(x%fx, &
            x%fy, x%moment), motor_gain=x%gain, integrator=x%method, rtol=x%rtol, dt=x%dt, &
            friction=x%law, friction_velocity=x%vslip), t_out, wrt, out, stat)
        if (stat%code /= STATUS_OK) return
        do k = 1, size(t_out)
            do i = 1, size(obs)
                call observe(out, obs(i), k, y(i, k), dy(i, k, :))
            end do
        end do
    contains
        !> The response by central differences of whole runs (x%fd).
        subroutine central_differences()
            real(dp), allocatable :: yp(:, :), ym(:, :), p(:)
            real(dp) :: h
            integer :: j
            dy = 0.0_dp
            call release_run(nbeams, params, x, t_out, obs, y, stat)
            if (stat%code /= STATUS_OK) return
            allocate (yp(size(y, 1), size(y, 2)), ym(size(y, 1), size(y, 2)))
            do j = 1, size(wrt)
                p = params
                h = 1.0e-4_dp*max(abs(params(wrt(j))), 1.0e-2_dp)
                p(wrt(j)) = params(wrt(j)) + h
                call release_run(nbeams, p, x, t_out, obs, yp, stat)
                if (stat%code /= STATUS_OK) return
                p(wrt(j)) = params(wrt(j)) - h
                call release_run(nbeams, p, x, t_out, obs, ym, stat)
                if (stat%code /= STATUS_OK) return
                dy(:, :, j) = (yp - ym)/(2.0_dp*h)
            end do
        end subroutine central_differences
    end subroutine release_response

    !> The release family's observe: the value of observation o at output
    !! time k of the response `out` and its derivatives d/d params(wrt)
    !! (grad empty: no derivatives, out%dy need not be there).
    subroutine observe(out, o, k, value, grad)
        type(release_out_t), intent(in) :: out
        type(observation_t), intent(in) :: o
        integer, intent(in) :: k
        real(dp), intent(out) :: value, grad(:)
        integer :: row
        value = 0.0_dp
        grad = 0.0_dp
        select case (o%kind)
        case (K_X_TIP)
            row = QTY_X_TIP
        case (K_Y_TIP)
            row = QTY_Y_TIP
        case (K_TIP_ANGLE)
            row = QTY_TIP_ANGLE
        case (K_X_ELBOW)
            row = QTY_X_ELBOW
        case (K_Y_ELBOW)
            row = QTY_Y_ELBOW
        case (K_U_TIP)
            row = QTY_U_TIP
        case (K_W_TIP)
            row = QTY_W_TIP
        case (K_MOTOR_TORQUE)
            row = QTY_MOTOR_TORQUE
        case default
            return
        end select
        value = out%y(row, k)
        if (size(grad) > 0) grad = out%dy(row, k, :)
    end subroutine observe

    !> One run: static equilibrium, release, integration, observations
    !! (no sensitivities: the central differences of x%fd).
    subroutine release_run(nbeams, params, x, t_out, obs, y, stat)
        integer, intent(in) :: nbeams
        real(dp), intent(in) :: params(:)
        type(release_exp_t), intent(in) :: x
        real(dp), intent(in) :: t_out(:)
        type(observation_t), intent(in) :: obs(:)
        real(dp), intent(out) :: y(:, :)
        type(status_t), intent(inout) :: stat
        type(chain_t) :: chain
        type(dyn_system_t) :: sys
        type(fe_newton_opts_t) :: nopts
        type(fe_solve_info_t) :: sinfo
        type(integ_opts_t) :: opts
        type(integ_stats_t) :: stats
        type(release_out_t) :: out
        real(dp), allocatable :: y0(:), q(:)
        real(dp) :: u, w, ang, ltot, none(0)
        integer :: k, n, i
        y = 0.0_dp
        call chain_from_vector(nbeams, params, chain, stat)
        if (stat%code /= STATUS_OK) return
        call dyn_setup(chain, x%nepb, x%gain, x%law, x%vslip, sys, stat)
        if (stat%code /= STATUS_OK) return
        n = sys%n
        allocate (y0(sys%nstate), q(n), source=0.0_dp)
        call fe_solve_static(sys%mesh, fe_load_t(x%fx, x%fy, x%moment), q, .false., nopts, &
                             sinfo, stat)
        if (stat%code /= STATUS_OK) return
        y0(1:n) = q
        opts%method = x%method
        if (x%dt > 0.0_dp) opts%dt = x%dt
        if (x%rtol > 0.0_dp) opts%rtol = x%rtol
        opts%atol = opts%rtol
        call integrate(sys, y0, t_out, opts, out%hist, stats, stat)
        if (stat%code /= STATUS_OK) return
        ltot = sum(chain%length)
        allocate (out%y(NQTY, size(t_out)), source=0.0_dp)
        do k = 1, size(t_out)
            associate (hy => out%hist%y(:, k))
                call dyn_tip(sys, hy(1:n), u, w, ang)
                out%y(QTY_U_TIP, k) = u
                out%y(QTY_W_TIP, k) = w
                out%y(QTY_X_TIP, k) = ltot + u
                out%y(QTY_Y_TIP, k) = w
                out%y(QTY_TIP_ANGLE, k) = ang
                if (sys%npt >= 2) then
                    out%y(QTY_X_ELBOW, k) = chain%length(1) + hy(sys%iu(1))
                    out%y(QTY_Y_ELBOW, k) = hy(sys%iw(1))
                end if
                out%y(QTY_MOTOR_TORQUE, k) = out%hist%torque(k)
            end associate
            do i = 1, size(obs)
                call observe(out, obs(i), k, y(i, k), none)
            end do
        end do
    end subroutine release_run

    !> Predictions and sensitivities of the rows: one response per experiment
    !! that has rows, at the distinct times of its rows. A release with a
    !! rough tolerance answers at it in ROUGH_ALL mode; in ROUGH_JACOBIAN mode
    !! with sensitivities asked it predicts from a plain run at its own
    !! tolerance (the cached one when the parameters are those of the last
    !! plain run) and differentiates at the rough one.
    subroutine dynamic_evaluate(self, params, wrt, predictions, jacobian, stat)
        class(dynamic_experiments_t), intent(inout) :: self
        real(dp), intent(in) :: params(:)
        integer, intent(in) :: wrt(:)
        real(dp), intent(out) :: predictions(:)
        real(dp), intent(out) :: jacobian(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: times(:), y(:, :), dy(:, :, :)
        type(release_exp_t) :: rough
        integer :: e, i, k, nobs
        predictions = 0.0_dp
        jacobian = 0.0_dp
        if (.not. allocated(self%cache)) allocate (self%cache(size(self%exps)))
        do e = 1, size(self%exps)
            if (.not. any(self%row_exp == e)) cycle
            times = distinct_sorted(pack(self%row_t, self%row_exp == e))
            nobs = size(self%eobs(e)%o)
            allocate (y(nobs, size(times)), dy(nobs, size(times), size(wrt)))
            if (self%rough == ROUGH_ALL .and. rough_tolerance(self%exps(e)) > 0.0_dp) then
                rough = self%exps(e)
                rough%rtol = rough_tolerance(rough)
                call release_response(self%nbeams, params, rough, times, wrt, self%eobs(e)%o, y, &
                                      dy, stat)
            else if (self%rough == ROUGH_JACOBIAN .and. size(wrt) > 0 .and. &
                     rough_tolerance(self%exps(e)) > 0.0_dp) then
                call rough_response(e, times, y, dy)
            else
                call release_response(self%nbeams, params, self%exps(e), times, wrt, &
                                      self%eobs(e)%o, y, dy, stat)
                if (stat%code == STATUS_OK .and. size(wrt) == 0) call remember(e, y)
            end if
            if (stat%code /= STATUS_OK) then
                stat%message = trim(stat%message)//' (experiment '//fmt_int(e)//')'
                return
            end if
            do i = 1, size(self%row_exp)
                if (self%row_exp(i) /= e) cycle
                k = findloc(times, self%row_t(i), 1)
                predictions(i) = y(self%row_oi(i), k)
                jacobian(i, :) = dy(self%row_oi(i), k, :)
            end do
            deallocate (y, dy)
        end do
    contains
        !> Predictions at the experiment's own tolerance (the cached plain
        !! run or a new one), sensitivities at its rough tolerance.
        subroutine rough_response(e, times, y, dy)
            integer, intent(in) :: e
            real(dp), intent(in) :: times(:)
            real(dp), intent(out) :: y(:, :), dy(:, :, :)
            real(dp), allocatable :: yr(:, :), none(:, :, :)
            logical :: cached
            cached = self%cache(e)%valid
            if (cached) cached = all(self%cache(e)%params == params)
            if (cached) then
                y = self%cache(e)%y
            else
                allocate (none(size(self%eobs(e)%o), size(times), 0))
                call release_response(self%nbeams, params, self%exps(e), times, wrt(1:0), &
                                      self%eobs(e)%o, y, none, stat)
                if (stat%code /= STATUS_OK) return
                call remember(e, y)
            end if
            rough = self%exps(e)
            rough%rtol = rough_tolerance(rough)
            allocate (yr(size(self%eobs(e)%o), size(times)))
            call release_response(self%nbeams, params, rough, times, wrt, self%eobs(e)%o, yr, &
                                  dy, stat)
        end subroutine rough_response

        subroutine remember(e, y)
            integer, intent(in) :: e
            real(dp), intent(in) :: y(:, :)
            self%cache(e)%valid = .true.
            self%cache(e)%params = params
            self%cache(e)%y = y
        end subroutine remember
    end subroutine dynamic_evaluate
end module beamid_dynamic_experiments
