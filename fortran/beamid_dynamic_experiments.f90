!> Dynamic experiments for the estimation machinery (Chapter IV.2, V.2).
!!
!! A release experiment holds the finite element model in static equilibrium
!! under a fixed-direction tip load (same mesh), releases it at rest at t = 0
!! and integrates M q'' + NLT(q) = Q(q, q') (Eq. 107), with the tip motor of
!! Eq. 159 when its gain is positive. A data row is (experiment, t, quantity,
!! value, sigma); t = 0 measures the static shape before the release.
!!
!! Quantities use the one registry of beamid_static_experiments (u_tip w_tip
!! x_tip y_tip tip_angle x_elbow y_elbow, plus motor_torque, which only a
!! release with a motor produces; wire_force is static only).
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
                              QTY_MOTOR_TORQUE
    use beamid_static_experiments, only: Q_X_TIP, Q_Y_TIP, Q_TIP_ANGLE, Q_WIRE_FORCE, &
                                         Q_X_ELBOW, Q_Y_ELBOW, Q_U_TIP, Q_W_TIP, &
                                         Q_MOTOR_TORQUE, NQUANT, distinct_sorted
    implicit none
    private

    public :: release_exp_t, dynamic_experiments_t, dynamic_experiments_init
    public :: release_response, check_dynamic_row

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

    !> The last plain run of an experiment: its parameters, output times and
    !! response (and the response's rates when they were asked).
    type :: plain_cache_t
        logical :: valid = .false.
        real(dp), allocatable :: params(:), times(:)
        real(dp), allocatable :: y(:, :), rate(:, :)
    end type plain_cache_t

    !> The row of release_out_t%y (QTY_* of beamid_release) that feeds each
    !! quantity code of the estimation registry (0: wire_force, none).
    integer, parameter :: QTY_OF(NQUANT) = [QTY_X_TIP, QTY_Y_TIP, QTY_TIP_ANGLE, 0, &
                                            QTY_X_ELBOW, QTY_Y_ELBOW, QTY_U_TIP, QTY_W_TIP, &
                                            QTY_MOTOR_TORQUE]

    !> Release experiments and the data rows they predict.
    type, extends(residual_model_t) :: dynamic_experiments_t
        integer :: nbeams = 0
        type(release_exp_t), allocatable :: exps(:)
        integer, allocatable :: row_exp(:), row_quantity(:)
        real(dp), allocatable :: row_t(:)
        type(plain_cache_t), allocatable :: cache(:) !< per experiment (rough mode)
        !> the model time at each experiment's record zero (its clock offset
        !! t0, set by beamid_inverse before evaluate): row i is predicted at
        !! model time max(0, row_t(i) + shift(row_exp(i))) (before the
        !! release the chain is at rest in its static shape)
        real(dp), allocatable :: shift(:)
        !> evaluate also returns d prediction / d t of every row in row_rate
        logical :: want_rates = .false.
        real(dp), allocatable :: row_rate(:)
    contains
        procedure :: evaluate => dynamic_evaluate
    end type dynamic_experiments_t

contains

    !> Why a row (t, quantity) cannot belong to release experiment `x`
    !! ('' when it can): t negative or not finite, wire_force, motor_torque
    !! without a motor.
    pure function check_dynamic_row(x, t, q) result(why)
        type(release_exp_t), intent(in) :: x
        real(dp), intent(in) :: t
        integer, intent(in) :: q
        character(len=:), allocatable :: why
        why = ''
        if (.not. ieee_is_finite(t)) then
            why = 'field t is not finite'
        else if (t < 0.0_dp) then
            why = 'field t = '//fmt_real(t)//', expected t >= 0 (0: the static shape '// &
                  'before the release)'
        else if (q < 1 .or. q > NQUANT) then
            why = 'quantity code '//fmt_int(q)//', expected 1..'//fmt_int(NQUANT)
        else if (q == Q_WIRE_FORCE) then
            why = "field quantity = 'wire_force', but a release experiment has no wire"
        else if (q == Q_MOTOR_TORQUE .and. .not. x%gain > 0.0_dp) then
            why = "field quantity = 'motor_torque', but the experiment has no motor "// &
                  '(motor_gain = 0)'
        end if
    end function check_dynamic_row

    !> Set up and validate the experiments and rows (the list lengths and
    !! experiment numbers as inverse_problem_init checked them).
    subroutine dynamic_experiments_init(nbeams, exps, row_exp, row_t, row_quantity, self, stat)
        integer, intent(in) :: nbeams
        type(release_exp_t), intent(in) :: exps(:)
        integer, intent(in) :: row_exp(:), row_quantity(:)
        real(dp), intent(in) :: row_t(:)
        type(dynamic_experiments_t), intent(out) :: self
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'dynamic experiments'
        character(len=:), allocatable :: why
        integer :: i
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
            why = check_dynamic_row(exps(row_exp(i)), row_t(i), row_quantity(i))
            if (len(why) > 0) then
                call set_status(stat, ERR_INPUT, where, 'row '//fmt_int(i)//': '//why)
                return
            end if
        end do
        self%nbeams = nbeams
        self%exps = exps
        self%row_exp = row_exp
        self%row_t = row_t
        self%row_quantity = row_quantity
        allocate (self%cache(size(exps)))
        allocate (self%shift(size(exps)), self%row_rate(size(row_exp)), source=0.0_dp)
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

    !> The response of one release at the ascending times t_out: y(q, k) for
    !! every quantity code q (the registry of beamid_static_experiments;
    !! wire_force is 0) and dy(q, k, j) = d y(q, k) / d params(wrt(j)), from
    !! the forward sensitivities of beamid_release (or central differences
    !! when x%fd).
    subroutine release_response(nbeams, params, x, t_out, wrt, y, dy, stat, rate)
        integer, intent(in) :: nbeams
        real(dp), intent(in) :: params(:)
        type(release_exp_t), intent(in) :: x
        real(dp), intent(in) :: t_out(:)
        integer, intent(in) :: wrt(:)
        real(dp), intent(out) :: y(:, :), dy(:, :, :)
        type(status_t), intent(inout) :: stat
        !> d y(q, k) / d t (the integrated state's rates: release_out_t%rate)
        real(dp), intent(out), optional :: rate(:, :)
        type(chain_t) :: chain
        type(release_out_t) :: out
        integer :: q
        if (x%fd) then
            call central_differences()
            if (present(rate) .and. stat%code == STATUS_OK) call plain_rates()
            return
        end if
        y = 0.0_dp
        dy = 0.0_dp
        call chain_from_vector(nbeams, params, chain, stat)
        if (stat%code /= STATUS_OK) return
        call sens_response(chain, release_spec_t(elements_per_beam=x%nepb, load=fe_load_t(x%fx, &
            x%fy, x%moment), motor_gain=x%gain, integrator=x%method, rtol=x%rtol, dt=x%dt, &
            friction=x%law, friction_velocity=x%vslip, rates=present(rate)), t_out, wrt, out, &
            stat)
        if (stat%code /= STATUS_OK) return
        if (present(rate)) rate = 0.0_dp
        do q = 1, NQUANT
            if (QTY_OF(q) == 0) cycle
            y(q, :) = out%y(QTY_OF(q), :)
            dy(q, :, :) = out%dy(QTY_OF(q), :, :)
            if (present(rate)) rate(q, :) = out%rate(QTY_OF(q), :)
        end do
    contains
        !> The rates of a central-difference release: one forward run more.
        subroutine plain_rates()
            call chain_from_vector(nbeams, params, chain, stat)
            if (stat%code /= STATUS_OK) return
            call sens_response(chain, release_spec_t(elements_per_beam=x%nepb, &
                load=fe_load_t(x%fx, x%fy, x%moment), motor_gain=x%gain, integrator=x%method, &
                rtol=x%rtol, dt=x%dt, friction=x%law, friction_velocity=x%vslip, rates=.true.), &
                t_out, wrt(1:0), out, stat)
            if (stat%code /= STATUS_OK) return
            rate = 0.0_dp
            do q = 1, NQUANT
                if (QTY_OF(q) /= 0) rate(q, :) = out%rate(QTY_OF(q), :)
            end do
        end subroutine plain_rates

        !> The response by central differences of whole runs (x%fd).
        subroutine central_differences()
            real(dp), allocatable :: yp(:, :), ym(:, :), p(:)
            real(dp) :: h
            integer :: j
            dy = 0.0_dp
            call release_run(nbeams, params, x, t_out, y, stat)
            if (stat%code /= STATUS_OK) return
            allocate (yp(size(y, 1), size(y, 2)), ym(size(y, 1), size(y, 2)))
            do j = 1, size(wrt)
                p = params
                h = 1.0e-4_dp*max(abs(params(wrt(j))), 1.0e-2_dp)
                p(wrt(j)) = params(wrt(j)) + h
                call release_run(nbeams, p, x, t_out, yp, stat)
                if (stat%code /= STATUS_OK) return
                p(wrt(j)) = params(wrt(j)) - h
                call release_run(nbeams, p, x, t_out, ym, stat)
                if (stat%code /= STATUS_OK) return
                dy(:, :, j) = (yp - ym)/(2.0_dp*h)
            end do
        end subroutine central_differences
    end subroutine release_response

    !> One run: static equilibrium, release, integration, quantities.
    subroutine release_run(nbeams, params, x, t_out, y, stat)
        integer, intent(in) :: nbeams
        real(dp), intent(in) :: params(:)
        type(release_exp_t), intent(in) :: x
        real(dp), intent(in) :: t_out(:)
        real(dp), intent(out) :: y(:, :)
        type(status_t), intent(inout) :: stat
        type(chain_t) :: chain
        type(dyn_system_t) :: sys
        type(fe_newton_opts_t) :: nopts
        type(fe_solve_info_t) :: sinfo
        type(integ_opts_t) :: opts
        type(integ_stats_t) :: stats
        type(history_t) :: hist
        real(dp), allocatable :: y0(:), q(:)
        real(dp) :: u, w, ang, ltot
        integer :: k, n
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
        call integrate(sys, y0, t_out, opts, hist, stats, stat)
        if (stat%code /= STATUS_OK) return
        ltot = sum(chain%length)
        do k = 1, size(t_out)
            call dyn_tip(sys, hist%y(1:n, k), u, w, ang)
            y(Q_U_TIP, k) = u
            y(Q_W_TIP, k) = w
            y(Q_X_TIP, k) = ltot + u
            y(Q_Y_TIP, k) = w
            y(Q_TIP_ANGLE, k) = ang
            if (sys%npt >= 2) then
                y(Q_X_ELBOW, k) = chain%length(1) + hist%y(sys%iu(1), k)
                y(Q_Y_ELBOW, k) = hist%y(sys%iw(1), k)
            end if
            y(Q_MOTOR_TORQUE, k) = hist%torque(k)
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
        real(dp), allocatable :: times(:), y(:, :), dy(:, :, :), rate(:, :), tm(:)
        type(release_exp_t) :: rough
        integer :: e, i, k
        logical :: rates
        predictions = 0.0_dp
        jacobian = 0.0_dp
        if (.not. allocated(self%cache)) allocate (self%cache(size(self%exps)))
        if (.not. allocated(self%shift)) allocate (self%shift(size(self%exps)), source=0.0_dp)
        if (.not. allocated(self%row_rate)) allocate (self%row_rate(size(self%row_exp)))
        self%row_rate = 0.0_dp
        rates = self%want_rates
        ! the model time of every row: its record time plus its record's offset
        tm = max(0.0_dp, self%row_t + self%shift(self%row_exp))
        do e = 1, size(self%exps)
            if (.not. any(self%row_exp == e)) cycle
            times = distinct_sorted(pack(tm, self%row_exp == e))
            allocate (y(NQUANT, size(times)), dy(NQUANT, size(times), size(wrt)), &
                      rate(NQUANT, size(times)), source=0.0_dp)
            if (self%rough == ROUGH_ALL .and. rough_tolerance(self%exps(e)) > 0.0_dp) then
                rough = self%exps(e)
                rough%rtol = rough_tolerance(rough)
                if (rates) then
                    call release_response(self%nbeams, params, rough, times, wrt, y, dy, stat, &
                                          rate)
                else
                    call release_response(self%nbeams, params, rough, times, wrt, y, dy, stat)
                end if
            else if (self%rough == ROUGH_JACOBIAN .and. size(wrt) > 0 .and. &
                     rough_tolerance(self%exps(e)) > 0.0_dp) then
                call rough_response(e, times, y, dy, rate)
            else
                if (rates) then
                    call release_response(self%nbeams, params, self%exps(e), times, wrt, y, dy, &
                                          stat, rate)
                else
                    call release_response(self%nbeams, params, self%exps(e), times, wrt, y, dy, &
                                          stat)
                end if
                if (stat%code == STATUS_OK .and. size(wrt) == 0) call remember(e, times, y, rate)
            end if
            if (stat%code /= STATUS_OK) then
                stat%message = trim(stat%message)//' (experiment '//fmt_int(e)//')'
                return
            end if
            do i = 1, size(self%row_exp)
                if (self%row_exp(i) /= e) cycle
                k = findloc(times, tm(i), 1)
                predictions(i) = y(self%row_quantity(i), k)
                jacobian(i, :) = dy(self%row_quantity(i), k, :)
                ! before the release (model time clipped at 0) the chain rests
                if (self%row_t(i) + self%shift(e) > 0.0_dp) &
                    self%row_rate(i) = rate(self%row_quantity(i), k)
            end do
            deallocate (y, dy, rate)
        end do
    contains
        !> Predictions at the experiment's own tolerance (the cached plain
        !! run or a new one), sensitivities at its rough tolerance.
        subroutine rough_response(e, times, y, dy, rate)
            integer, intent(in) :: e
            real(dp), intent(in) :: times(:)
            real(dp), intent(out) :: y(:, :), dy(:, :, :), rate(:, :)
            real(dp), allocatable :: yr(:, :), none(:, :, :)
            logical :: cached
            cached = self%cache(e)%valid
            if (cached) cached = size(self%cache(e)%times) == size(times) .and. &
                                 size(self%cache(e)%params) == size(params)
            if (cached) cached = all(self%cache(e)%params == params) .and. &
                                 all(self%cache(e)%times == times) .and. &
                                 (allocated(self%cache(e)%rate) .or. .not. rates)
            rate = 0.0_dp
            if (cached) then
                y = self%cache(e)%y
                if (rates) rate = self%cache(e)%rate
            else
                allocate (none(NQUANT, size(times), 0))
                if (rates) then
                    call release_response(self%nbeams, params, self%exps(e), times, wrt(1:0), &
                                          y, none, stat, rate)
                else
                    call release_response(self%nbeams, params, self%exps(e), times, wrt(1:0), &
                                          y, none, stat)
                end if
                if (stat%code /= STATUS_OK) return
                call remember(e, times, y, rate)
            end if
            rough = self%exps(e)
            rough%rtol = rough_tolerance(rough)
            allocate (yr(NQUANT, size(times)))
            call release_response(self%nbeams, params, rough, times, wrt, yr, dy, stat)
        end subroutine rough_response

        subroutine remember(e, times, y, rate)
            integer, intent(in) :: e
            real(dp), intent(in) :: times(:), y(:, :), rate(:, :)
            self%cache(e)%valid = .true.
            self%cache(e)%params = params
            self%cache(e)%times = times
            self%cache(e)%y = y
            if (rates) then
                self%cache(e)%rate = rate
            else if (allocated(self%cache(e)%rate)) then
                deallocate (self%cache(e)%rate)
            end if
        end subroutine remember
    end subroutine dynamic_evaluate
end module beamid_dynamic_experiments
