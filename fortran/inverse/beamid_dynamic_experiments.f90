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
    use beamid_dynamics, only: dyn_system_t, dyn_setup, dyn_tip, FRICTION_SIGN, dyn_param_t, &
                               dyn_param_setup, damping_element, DP_NONE
    use beamid_integrators, only: integ_opts_t, integ_stats_t, history_t, integrate, &
                                  METHOD_IMPLICIT, METHOD_RK4, integ_rate_sens
    use beamid_fe_element, only: fe_hermite, FE_U, FE_W, FE_NDOF, fe_element_mass, &
                                 fe_element_tangent_tabulated, fe_element_force_tabulated
    use beamid_model, only: param_count, param_index_beam, param_index_global, IB_EI, IB_C, &
                            IB_EA, IB_RHO, IG_ETA, param_index_thickness
    use beamid_estimation, only: residual_model_t, ROUGH_JACOBIAN, ROUGH_ALL
    use beamid_hub, only: hub_forcing_t
    use beamid_loads, only: tip_history_t, histories_from_columns, history_check, LD_NSPEC
    use beamid_release, only: release_spec_t, release_out_t, release_add_loads, &
                              sens_response => release_response, QTY_U_TIP, QTY_W_TIP, &
                              QTY_X_TIP, QTY_Y_TIP, QTY_TIP_ANGLE, QTY_X_ELBOW, QTY_Y_ELBOW, &
                              QTY_MOTOR_TORQUE, NQTY, WRT_V0
    use beamid_static_experiments, only: distinct_sorted
    use beamid_family, only: experiment_family_t, family_input_t, EV_FX, EV_FY, EV_MOMENT, &
                             EV_NEPB, EV_GAIN, EV_METHOD, EV_LAW, EV_RTOL, EV_DT, EV_VSLIP, EV_FD
    use beamid_observations, only: observation_t, observation_why_not, same_observation, &
                                   FAM_RELEASE, why_detail, WHY_OK, WHY_WIRE, WHY_MOTOR, WHY_FAMILY, &
                                   K_X_TIP, K_Y_TIP, K_TIP_ANGLE, K_X_ELBOW, K_Y_ELBOW, K_U_TIP, &
                                   K_W_TIP, K_MOTOR_TORQUE, kind_label, KINDS, LOCUS_STATION, &
                                   K_X, K_Y, K_PSI, K_CURVATURE, K_MOMENT, K_STRAIN, K_VEL_T, &
                                   K_VEL_N, K_ACCEL_T, K_ACCEL_N, &
                                   K_ELBOW_ROTATION, K_ROOT_ROTATION, K_REACTION_X, &
                                   K_REACTION_Y, K_REACTION_MOMENT, K_HUB_TORQUE
    implicit none
    private

    public :: release_exp_t, dynamic_experiments_t, dynamic_experiments_init
    public :: release_response, check_dynamic_row, observe, attach_histories

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
        real(dp) :: v0 = 0.0_dp   !< initial tip normal velocity (the chain's nuisance)
        !> sensitivities at the experiment's own tolerance at every fit
        !! iteration (no rough Jacobian: fit(..., jacobian="exact"))
        logical :: exact = .false.
        !> load histories at the tip and a prescribed hub rotation from t = 0
        !! (release_spec_t's fields of the same names; beamid_loads,
        !! beamid_hub): a forced response, a hammer test, a spin-up
        type(tip_history_t), allocatable :: histories(:)
        logical :: hub = .false.
        real(dp) :: hub_ws = 0.0_dp, hub_period = 0.0_dp
        real(dp), allocatable :: hub_table(:, :)
    end type release_exp_t

    !> The load histories of a problem's experiments as the binding
    !! marshals them (their own list beside the experiments' specs):
    !! column l of spec is [experiment, then beamid_loads' LD_NSPEC values],
    !! the table rows in tab (2, :) (t, value) that the columns' first-row
    !! indices refer to.
    type, public :: exp_histories_t
        real(dp), allocatable :: spec(:, :)
        real(dp), allocatable :: tab(:, :)
    end type exp_histories_t

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

    !> A list of observations.
    type :: obs_list_t
        type(observation_t), allocatable :: o(:)
    end type obs_list_t

    !> Release experiments and the data rows they predict: the release
    !! family of the inverse problem (experiment kind EXP_RELEASE). Its
    !! clock offsets (shift: row i is predicted at model time
    !! max(0, row_t(i) + shift(row_exp(i))); before the release the chain is
    !! at rest in its static shape) and rates (want_rates, row_rate) are the
    !! timed family's components of experiment_family_t.
    type, extends(experiment_family_t) :: dynamic_experiments_t
        type(release_exp_t), allocatable :: exps(:)
        !> the distinct observations of each experiment's rows, and the
        !! index of each row's observation in its experiment's list
        type(obs_list_t), allocatable :: eobs(:)
        integer, allocatable :: row_oi(:)
        real(dp), allocatable :: row_t(:)
        type(plain_cache_t), allocatable :: cache(:) !< per experiment (rough mode)
    contains
        procedure :: evaluate => dynamic_evaluate
        procedure :: build => release_build
    end type dynamic_experiments_t

contains

    !> The family's constructor for the problem: a release_exp_t per
    !! experiment from its spec, then dynamic_experiments_init.
    subroutine release_build(self, input, stat)
        class(dynamic_experiments_t), intent(inout) :: self
        type(family_input_t), intent(in) :: input
        type(status_t), intent(inout) :: stat
        type(release_exp_t), allocatable :: rels(:)
        integer :: e
        allocate (rels(size(input%kinds)))
        do e = 1, size(input%kinds)
            associate (v => input%specs(e))
                rels(e) = release_exp_t(fx=v%get(EV_FX), fy=v%get(EV_FY), &
                                        moment=v%get(EV_MOMENT), nepb=v%get_int(EV_NEPB), &
                                        gain=v%get(EV_GAIN), method=v%get_int(EV_METHOD), &
                                        law=v%get_int(EV_LAW), rtol=v%get(EV_RTOL), &
                                        dt=v%get(EV_DT), &
                                        vslip=merge(v%get(EV_VSLIP), 1.0e-4_dp, &
                                                    v%get(EV_VSLIP) > 0.0_dp), &
                                        fd=v%get_int(EV_FD) == 1, exact=v%get_int(EV_FD) == 2)
            end associate
        end do
        call dynamic_experiments_init(input, rels, self, stat)
        ! a release's predictions do not depend on the sensitivities asked,
        ! which cost several runs: the fit judges its trial steps without them
        self%plain_trials = .true.
    end subroutine release_build

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
    subroutine dynamic_experiments_init(input, exps, self, stat)
        type(family_input_t), intent(in) :: input
        type(release_exp_t), intent(in) :: exps(:)
        type(dynamic_experiments_t), intent(out) :: self
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'dynamic experiments'
        character(len=:), allocatable :: why
        integer :: i, e
        do i = 1, size(exps)
            if (.not. (exps(i)%gain >= 0.0_dp .and. ieee_is_finite(exps(i)%gain))) then
                call set_status(stat, ERR_INPUT, where, 'experiment '//fmt_int(i)// &
                                ': motor_gain = '//fmt_real(exps(i)%gain)//', expected >= 0')
                return
            end if
        end do
        do i = 1, size(input%row_exp)
            why = check_dynamic_row(exps(input%row_exp(i)), input%row_t(i), input%row_obs(i), &
                                    input%nbeams)
            if (len(why) > 0) then
                call set_status(stat, ERR_INPUT, where, 'row '//fmt_int(i)//': '//why)
                return
            end if
        end do
        self%exps = exps
        self%row_t = input%row_t
        allocate (self%eobs(size(exps)), self%row_oi(size(input%row_exp)))
        do i = 1, size(exps)
            allocate (self%eobs(i)%o(0))
        end do
        do i = 1, size(input%row_exp)
            e = input%row_exp(i)
            self%row_oi(i) = 0
            if (size(self%eobs(e)%o) > 0) &
                self%row_oi(i) = findloc(same_observation(self%eobs(e)%o, input%row_obs(i)), &
                                         .true., 1)
            if (self%row_oi(i) == 0) then
                self%eobs(e)%o = [self%eobs(e)%o, input%row_obs(i)]
                self%row_oi(i) = size(self%eobs(e)%o)
            end if
        end do
        allocate (self%cache(size(exps)))
        allocate (self%shift(size(exps)), self%row_rate(size(input%row_exp)), source=0.0_dp)
        self%rough_jacobian_ok = .false.
        do i = 1, size(exps)
            if (.not. any(input%row_exp == i)) cycle
            if (rough_tolerance(exps(i)) > 0.0_dp) self%rough_jacobian_ok = .true.
        end do
    end subroutine dynamic_experiments_init

    !> The release_spec_t of experiment x (its histories and hub included).
    function exp_spec(x, rates) result(spec)
        type(release_exp_t), intent(in) :: x
        logical, intent(in) :: rates
        type(release_spec_t) :: spec
        spec = release_spec_t(elements_per_beam=x%nepb, load=fe_load_t(x%fx, x%fy, x%moment), &
                              motor_gain=x%gain, integrator=x%method, rtol=x%rtol, dt=x%dt, &
                              friction=x%law, friction_velocity=x%vslip, rates=rates)
        spec%v0 = x%v0
        if (allocated(x%histories)) spec%histories = x%histories
        spec%hub = x%hub
        spec%hub_ws = x%hub_ws
        spec%hub_period = x%hub_period
        if (allocated(x%hub_table)) spec%hub_table = x%hub_table
    end function exp_spec

    !> Add x's load histories and hub to a system set up for it (the
    !! station observations' and the plain runs' systems; release_add_loads).
    subroutine add_loads(sys, x, stat)
        type(dyn_system_t), intent(inout) :: sys
        type(release_exp_t), intent(in) :: x
        type(status_t), intent(inout) :: stat
        integer :: nhp
        if (.not. (allocated(x%histories) .or. x%hub)) return
        call release_add_loads(sys, exp_spec(x, .false.), huge(1.0_dp), nhp, stat)
    end subroutine add_loads

    !> Attach the histories of `hist` (columns whose experiment is `e`) to
    !! release experiment x, checked against its last data time t_end
    !! (a history starting after it is refused, naming the experiment).
    subroutine attach_histories(hist, e, t_end, x, stat)
        type(exp_histories_t), intent(in) :: hist
        integer, intent(in) :: e
        real(dp), intent(in) :: t_end
        type(release_exp_t), intent(inout) :: x
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: cols(:, :), tab(:, :)
        real(dp) :: hub(2)
        integer :: l
        if (.not. allocated(hist%spec)) return
        if (size(hist%spec, 2) == 0) return
        if (size(hist%spec, 1) /= LD_NSPEC + 1) then
            call set_status(stat, ERR_INPUT, 'experiment histories', 'columns of '// &
                            fmt_int(size(hist%spec, 1))//' values, expected '// &
                            fmt_int(LD_NSPEC + 1)//' (experiment, then the history)')
            return
        end if
        cols = hist%spec(2:, pack([(l, l=1, size(hist%spec, 2))], nint(hist%spec(1, :)) == e))
        if (size(cols, 2) == 0) return
        if (allocated(hist%tab)) then
            tab = hist%tab
        else
            allocate (tab(2, 0))
        end if
        call histories_from_columns(cols, tab, x%histories, stat, hub, x%hub, x%hub_table)
        if (stat%code /= STATUS_OK) then
            stat%message = 'experiment '//fmt_int(e)//': '//trim(stat%message)
            return
        end if
        x%hub_ws = hub(1)
        x%hub_period = hub(2)
        do l = 1, size(x%histories)
            call history_check(x%histories(l)%hist, 'experiment '//fmt_int(e)// &
                               ': load history '//fmt_int(l)//' ('// &
                               trim(x%histories(l)%name)//')', t_end, stat)
            if (stat%code /= STATUS_OK) return
        end do
    end subroutine attach_histories

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
    !! central differences when x%fd); with `rate` also d y(i, k) / d t
    !! (observation_rates: the column of a record's clock offset).
    subroutine release_response(nbeams, params, x, t_out, wrt, obs, y, dy, stat, rate)
        integer, intent(in) :: nbeams
        real(dp), intent(in) :: params(:)
        type(release_exp_t), intent(in) :: x
        real(dp), intent(in) :: t_out(:)
        integer, intent(in) :: wrt(:)
        type(observation_t), intent(in) :: obs(:)
        real(dp), intent(out) :: y(:, :), dy(:, :, :)
        type(status_t), intent(inout) :: stat
        !> d y(i, k) / d t (observation_rates)
        real(dp), intent(out), optional :: rate(:, :)
        type(chain_t) :: chain
        type(release_out_t) :: out
        type(dyn_system_t) :: sys
        type(dyn_param_t), allocatable :: pars(:)
        real(dp), allocatable :: a(:), da(:, :)
        logical :: accel
        integer :: i, k
        if (x%fd) then
            call central_differences()
            if (present(rate) .and. stat%code == STATUS_OK) call plain_rates()
            return
        end if
        y = 0.0_dp
        dy = 0.0_dp
        call chain_from_vector(nbeams, params, chain, stat)
        if (stat%code /= STATUS_OK) return
        call sens_response(chain, exp_spec(x, present(rate)), t_out, wrt, out, stat)
        if (stat%code /= STATUS_OK) return
        call station_setup(chain, x, wrt, obs, size(wrt) > 0, sys, pars, accel, stat)
        if (stat%code /= STATUS_OK) return
        allocate (a(sys%nstate), da(sys%nstate, size(wrt)))
        do k = 1, size(t_out)
            if (accel) call integ_rate_sens(sys, pars, t_out(k), out%hist%y(:, k), &
                                            out%dstates(:, k, :), a, da, stat)
            if (stat%code /= STATUS_OK) return
            if (accel .and. t_out(k) <= 0.0_dp) then
                ! t = 0 is the static shape before the release: at rest
                a = 0.0_dp
                da = 0.0_dp
            end if
            do i = 1, size(obs)
                if (is_reaction(obs(i)%kind)) then
                    call observe_reaction(sys, chain, obs(i)%kind, wrt, out%hist%y(:, k), &
                                          out%dstates(:, k, :), a, da, t_out(k) <= 0.0_dp, &
                                          y(i, k), dy(i, k, :))
                else if (root_kind(obs(i)%kind)) then
                    call observe_encoder(sys, chain, obs(i), wrt, out%hist%y(:, k), &
                                         out%dstates(:, k, :), y(i, k), dy(i, k, :))
                else if (KINDS(obs(i)%kind)%locus == LOCUS_STATION) then
                    call observe_station(sys, chain, obs(i), wrt, out%hist%y(:, k), &
                                         out%dstates(:, k, :), a, da, y(i, k), dy(i, k, :), &
                                         hub_rates(sys, t_out(k)))
                else
                    call observe(out, obs(i), k, y(i, k), dy(i, k, :))
                end if
            end do
        end do
        if (present(rate)) call observation_rates(chain, x, obs, t_out, out, rate, stat)
    contains
        !> The rates of a central-difference release: one forward run more.
        subroutine plain_rates()
            call chain_from_vector(nbeams, params, chain, stat)
            if (stat%code /= STATUS_OK) return
            call sens_response(chain, exp_spec(x, .true.), t_out, wrt(1:0), out, stat)
            if (stat%code /= STATUS_OK) return
            call observation_rates(chain, x, obs, t_out, out, rate, stat)
        end subroutine plain_rates

        !> The response by central differences of whole runs (x%fd).
        subroutine central_differences()
            real(dp), allocatable :: yp(:, :), ym(:, :), p(:)
            type(release_exp_t) :: xv
            real(dp) :: h
            integer :: j
            dy = 0.0_dp
            call release_run(nbeams, params, x, t_out, obs, y, stat)
            if (stat%code /= STATUS_OK) return
            allocate (yp(size(y, 1), size(y, 2)), ym(size(y, 1), size(y, 2)))
            do j = 1, size(wrt)
                if (wrt(j) == WRT_V0) then
                    xv = x
                    h = 1.0e-4_dp*max(abs(x%v0), 1.0e-2_dp)
                    xv%v0 = x%v0 + h
                    call release_run(nbeams, params, xv, t_out, obs, yp, stat)
                    if (stat%code /= STATUS_OK) return
                    xv%v0 = x%v0 - h
                    call release_run(nbeams, params, xv, t_out, obs, ym, stat)
                    if (stat%code /= STATUS_OK) return
                    dy(:, :, j) = (yp - ym)/(2.0_dp*h)
                    cycle
                end if
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
        row = qty_row(o%kind)
        if (row == 0) return
        value = out%y(row, k)
        if (size(grad) > 0) grad = out%dy(row, k, :)
    end subroutine observe

    !> The row of release_out_t%y (QTY_* of beamid_release) of a fixed-point
    !! kind (0: a kind beamid_release does not export).
    pure integer function qty_row(kind) result(row)
        integer, intent(in) :: kind
        select case (kind)
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
            row = 0
        end select
    end function qty_row

    !> Time derivatives rate(i, k) of the observations obs(i) at the output
    !! times t_out of a response computed with spec%rates (the column of a
    !! record's clock offset, beamid_inverse EV_T0): the fixed points' from
    !! out%rate (beamid_release quantity_rates: the velocities, the tip
    !! angle's chain rule, the motor torque's rate); a station's and an
    !! encoder's as observe_station's directional derivative along the
    !! state's rate f(t, y) (positions, angles, curvature, moment and strain
    !! along the velocities, the station velocities along the
    !! accelerations). An acceleration's rate would need the jerk: it is left
    !! 0 here and beamid_inverse refuses a clock offset on a record with
    !! acceleration rows. At t <= 0 the chain rests: every rate is 0.
    subroutine observation_rates(chain, x, obs, t_out, out, rate, stat)
        type(chain_t), intent(in) :: chain
        type(release_exp_t), intent(in) :: x
        type(observation_t), intent(in) :: obs(:)
        real(dp), intent(in) :: t_out(:)
        type(release_out_t), intent(in) :: out
        real(dp), intent(out) :: rate(:, :)
        type(status_t), intent(inout) :: stat
        type(dyn_system_t) :: sys
        type(dyn_param_t), allocatable :: pars(:)
        real(dp), allocatable :: f(:, :)
        real(dp) :: value, g(1), none(0), nos(0, 0), nod(0, 0)
        logical :: local(size(obs))
        integer :: i, k, row
        rate = 0.0_dp
        local = [(KINDS(obs(i)%kind)%locus == LOCUS_STATION .or. &
                  root_kind(obs(i)%kind), &
                  i=1, size(obs))]
        if (any(local)) then
            call dyn_setup(chain, x%nepb, x%gain, x%law, x%vslip, sys, stat)
            if (stat%code == STATUS_OK) call add_loads(sys, x, stat)
            if (stat%code /= STATUS_OK) return
            allocate (pars(0), f(sys%nstate, 1))
        end if
        do k = 1, size(t_out)
            if (t_out(k) <= 0.0_dp) cycle
            if (any(local)) then
                call integ_rate_sens(sys, pars, t_out(k), out%hist%y(:, k), nos, f(:, 1), nod, &
                                     stat)
                if (stat%code /= STATUS_OK) return
            end if
            do i = 1, size(obs)
                if (needs_accel(obs(i)%kind)) cycle
                if (root_kind(obs(i)%kind)) then
                    call observe_encoder(sys, chain, obs(i), [0], out%hist%y(:, k), f, value, g)
                    rate(i, k) = g(1)
                else if (local(i)) then
                    call observe_station(sys, chain, obs(i), [0], out%hist%y(:, k), f, none, &
                                         nod, value, g)
                    rate(i, k) = g(1)
                else
                    row = qty_row(obs(i)%kind)
                    if (row > 0) rate(i, k) = out%rate(row, k)
                end if
            end do
        end do
    end subroutine observation_rates

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
        type(dyn_param_t), allocatable :: pars(:)
        real(dp), allocatable :: y0(:), q(:), a(:)
        real(dp) :: u, w, ang, ltot, none(0), nos(0, 0), noda(0, 0)
        logical :: accel
        integer :: k, n, i
        y = 0.0_dp
        call chain_from_vector(nbeams, params, chain, stat)
        if (stat%code /= STATUS_OK) return
        call dyn_setup(chain, x%nepb, x%gain, x%law, x%vslip, sys, stat)
        if (stat%code == STATUS_OK) call add_loads(sys, x, stat)
        if (stat%code /= STATUS_OK) return
        n = sys%n
        allocate (y0(sys%nstate), q(n), source=0.0_dp)
        call fe_solve_static(sys%mesh, fe_load_t(x%fx, x%fy, x%moment), q, .false., nopts, &
                             sinfo, stat)
        if (stat%code /= STATUS_OK) return
        y0(1:n) = q
        if (x%v0 /= 0.0_dp) then
            ! the initial velocity field (beamid_release): the static shape
            ! scaled to tip normal velocity v0
            call dyn_tip(sys, q, u, w, ang)
            if (abs(w) <= 1.0e-12_dp*sum(chain%length)) then
                call set_status(stat, ERR_INPUT, 'release', 'an initial velocity v0 = '// &
                                fmt_real(x%v0)//', but the static shape has no tip '// &
                                'deflection; expected a release load that deflects the tip')
                return
            end if
            y0(n + 1:2*n) = x%v0*q/w
        end if
        opts%method = x%method
        if (x%dt > 0.0_dp) opts%dt = x%dt
        if (x%rtol > 0.0_dp) opts%rtol = x%rtol
        opts%atol = opts%rtol
        call integrate(sys, y0, t_out, opts, out%hist, stats, stat)
        if (stat%code /= STATUS_OK) return
        ltot = sum(chain%length)
        allocate (out%y(NQTY, size(t_out)), source=0.0_dp)
        allocate (pars(0), a(sys%nstate))
        accel = any([(needs_accel(obs(i)%kind), i=1, size(obs))])
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
            if (accel) call integ_rate_sens(sys, pars, t_out(k), out%hist%y(:, k), nos, a, noda, &
                                            stat)
            if (stat%code /= STATUS_OK) return
            if (accel .and. t_out(k) <= 0.0_dp) a = 0.0_dp   ! before the release: at rest
            do i = 1, size(obs)
                if (is_reaction(obs(i)%kind)) then
                    call observe_reaction(sys, chain, obs(i)%kind, [integer ::], &
                                          out%hist%y(:, k), nos, a, noda, t_out(k) <= 0.0_dp, &
                                          y(i, k), none)
                else if (root_kind(obs(i)%kind)) then
                    call observe_encoder(sys, chain, obs(i), [integer ::], out%hist%y(:, k), &
                                         nos, y(i, k), none)
                else if (KINDS(obs(i)%kind)%locus == LOCUS_STATION) then
                    call observe_station(sys, chain, obs(i), [integer ::], out%hist%y(:, k), &
                                         nos, a, noda, y(i, k), none, hub_rates(sys, t_out(k)))
                else
                    call observe(out, obs(i), k, y(i, k), none)
                end if
            end do
        end do
    end subroutine release_run

    !> What station observations need besides the response: the system (its
    !! mesh) and, for accelerations, the parameters' derivative kinds
    !! (accel: some observation is an acceleration).
    subroutine station_setup(chain, x, wrt, obs, with_pars, sys, pars, accel, stat)
        type(chain_t), intent(in) :: chain
        type(release_exp_t), intent(in) :: x
        integer, intent(in) :: wrt(:)
        type(observation_t), intent(in) :: obs(:)
        logical, intent(in) :: with_pars
        type(dyn_system_t), intent(out) :: sys
        type(dyn_param_t), allocatable, intent(out) :: pars(:)
        logical, intent(out) :: accel
        type(status_t), intent(inout) :: stat
        integer :: i, j
        allocate (pars(0))
        accel = any([(needs_accel(obs(i)%kind), i=1, size(obs))])
        if (.not. any([(KINDS(obs(i)%kind)%locus == LOCUS_STATION .or. &
                        root_kind(obs(i)%kind) .or. is_reaction(obs(i)%kind), &
                        i=1, size(obs))])) return
        call dyn_setup(chain, x%nepb, x%gain, x%law, x%vslip, sys, stat)
        if (stat%code == STATUS_OK) call add_loads(sys, x, stat)
        if (stat%code /= STATUS_OK .or. .not. (accel .and. with_pars)) return
        deallocate (pars)
        allocate (pars(size(wrt)))
        do j = 1, size(wrt)
            if (wrt(j) == WRT_V0) then
                pars(j)%kind = DP_NONE   ! the initial velocity: no forcing
                cycle
            end if
            call dyn_param_setup(sys, chain, wrt(j) - param_count(chain%nbeams), wrt(j), &
                                 pars(j), stat)
            if (stat%code /= STATUS_OK) return
        end do
    end subroutine station_setup

    !> Kinds of the clamp's load cell.
    elemental logical function is_reaction(kind)
        integer, intent(in) :: kind
        is_reaction = kind == K_REACTION_X .or. kind == K_REACTION_Y .or. &
                      kind == K_REACTION_MOMENT
    end function is_reaction

    !> Kinds that need the accelerations (and whose rate would need the
    !! jerk): the accelerometers and the load cell.
    elemental logical function needs_accel(kind)
        integer, intent(in) :: kind
        needs_accel = kind == K_ACCEL_T .or. kind == K_ACCEL_N .or. is_reaction(kind)
    end function needs_accel

    !> The clamp's load cell in a release (kind K_REACTION_X, _Y, _MOMENT):
    !! the clamped rows of the first element's equation of motion, G = M_e
    !! a_e + f_e(q_e) + fd_e(q_e, v_e) (inertia, internal force, Kelvin-Voigt
    !! damping; the Lagrange multipliers of the clamp, Eq. 104-107), are the
    !! force the clamp exerts on the arm: x from the u row, y from the w row;
    !! its moment (counter-clockwise) is the virtual work of a rigid rotation
    !! of the root node, G_w' (1 + u') - G_u' w' (the root node's slopes).
    !! `at_rest` (t <= 0: the static shape before the release) takes a = 0.
    !! y, sy: the state and its sensitivities; a, da: the state's rates and
    !! theirs.
    pure subroutine observe_reaction(sys, chain, kind, wrt, y, sy, a, da, at_rest, value, grad)
        type(dyn_system_t), intent(in) :: sys
        type(chain_t), intent(in) :: chain
        integer, intent(in) :: kind
        integer, intent(in) :: wrt(:)
        real(dp), intent(in) :: y(:), sy(:, :), a(:), da(:, :)
        logical, intent(in) :: at_rest
        real(dp), intent(out) :: value, grad(:)
        real(dp) :: qe(FE_NDOF), ve(FE_NDOF), ae(FE_NDOF), fe(FE_NDOF), ke(FE_NDOF, FE_NDOF)
        real(dp) :: me(FE_NDOF, FE_NDOF), fd(FE_NDOF), kd(FE_NDOF, FE_NDOF)
        real(dp) :: cd(FE_NDOF, FE_NDOF), unit(FE_NDOF), power, g(FE_NDOF)
        real(dp) :: dqe(FE_NDOF, size(grad)), dve(FE_NDOF, size(grad))
        real(dp) :: dae(FE_NDOF, size(grad)), dg(FE_NDOF, size(grad))
        integer :: j, m, n, nb, ng
        n = sys%n
        nb = chain%nbeams
        qe = 0.0_dp
        ve = 0.0_dp
        ae = 0.0_dp
        dqe = 0.0_dp
        dve = 0.0_dp
        dae = 0.0_dp
        do m = 1, FE_NDOF
            j = sys%mesh%el_free(m, 1)
            if (j == 0) cycle
            qe(m) = y(j)
            ve(m) = y(n + j)
            if (.not. at_rest .and. size(a) >= 2*n) ae(m) = a(n + j)
            if (size(grad) > 0) then
                dqe(m, :) = sy(j, :)
                dve(m, :) = sy(n + j, :)
                if (.not. at_rest .and. size(da, 1) >= 2*n) dae(m, :) = da(n + j, :)
            end if
        end do
        associate (mesh => sys%mesh)
            ng = size(mesh%xg)
            call fe_element_tangent_tabulated(ng, mesh%gauss_d1(:, :, 1), mesh%gauss_d2(:, :, 1), &
                                              mesh%gauss_wh(:, 1), mesh%ea(1), mesh%ei(1), &
                                              mesh%cubic(1), qe, ke, fe)
            call fe_element_mass(mesh%h(1), mesh%rho(1), me)
            g = fe + matmul(me, ae)
            dg = matmul(ke, dqe) + matmul(me, dae)
            if (sys%eta /= 0.0_dp) then
                call damping_element(mesh%h(1), sys%eta*mesh%ei(1), mesh%xg, mesh%wg, qe, ve, &
                                     fd, power, kd, cd)
                g = g + fd
                dg = dg + matmul(kd, dqe) + matmul(cd, dve)
            end if
            ! the parameters that enter the first element's equation directly:
            ! f_e is linear in (EA, EI, C), M_e in rho, fd in eta EI
            do j = 1, size(wrt)
                if (wrt(j) == param_index_beam(nb, 1, IB_EA)) then
                    call fe_element_force_tabulated(ng, mesh%gauss_d1(:, :, 1), &
                                                    mesh%gauss_d2(:, :, 1), mesh%gauss_wh(:, 1), &
                                                    1.0_dp, 0.0_dp, 0.0_dp, qe, unit)
                    dg(:, j) = dg(:, j) + unit
                else if (wrt(j) == param_index_beam(nb, 1, IB_EI)) then
                    call fe_element_force_tabulated(ng, mesh%gauss_d1(:, :, 1), &
                                                    mesh%gauss_d2(:, :, 1), mesh%gauss_wh(:, 1), &
                                                    0.0_dp, 1.0_dp, 0.0_dp, qe, unit)
                    dg(:, j) = dg(:, j) + unit
                    if (sys%eta /= 0.0_dp) dg(:, j) = dg(:, j) + fd/mesh%ei(1)
                else if (wrt(j) == param_index_beam(nb, 1, IB_C)) then
                    call fe_element_force_tabulated(ng, mesh%gauss_d1(:, :, 1), &
                                                    mesh%gauss_d2(:, :, 1), mesh%gauss_wh(:, 1), &
                                                    0.0_dp, 0.0_dp, 1.0_dp, qe, unit)
                    dg(:, j) = dg(:, j) + unit
                else if (wrt(j) == param_index_beam(nb, 1, IB_RHO)) then
                    call fe_element_mass(mesh%h(1), 1.0_dp, me)
                    dg(:, j) = dg(:, j) + matmul(me, ae)
                else if (wrt(j) == param_index_global(nb, IG_ETA)) then
                    call damping_element(mesh%h(1), mesh%ei(1), mesh%xg, mesh%wg, qe, ve, unit, &
                                         power)
                    dg(:, j) = dg(:, j) + unit
                end if
            end do
        end associate
        ! element unknowns of the root node: w, w', u, u'
        select case (kind)
        case (K_REACTION_X)
            value = g(3)
            grad = dg(3, :)
        case (K_REACTION_Y)
            value = g(1)
            grad = dg(1, :)
        case default
            value = g(2)*(1.0_dp + qe(4)) - g(4)*qe(2)
            grad = dg(2, :)*(1.0_dp + qe(4)) + g(2)*dqe(4, :) - dg(4, :)*qe(2) - g(4)*dqe(2, :)
        end select
    end subroutine observe_reaction

    !> The encoders of a release: psi at the clamp (root_rotation), psi
    !! after the elbow minus psi before it (elbow_rotation), from the slopes
    !! either side of the joint (observe_station at s = 0 of beam 2 and s =
    !! L1 of beam 1): zero unless the joint is compliant.
    pure subroutine observe_encoder(sys, chain, o, wrt, y, sy, value, grad)
        type(dyn_system_t), intent(in) :: sys
        type(chain_t), intent(in) :: chain
        type(observation_t), intent(in) :: o
        integer, intent(in) :: wrt(:)
        real(dp), intent(in) :: y(:), sy(:, :)
        real(dp), intent(out) :: value, grad(:)
        real(dp) :: v1, g1(size(grad)), none(0), nod(0, 0)
        if (o%kind == K_HUB_TORQUE) then
            ! the clamp's moment on the arm balances the internal moment M(0)
            call observe_station(sys, chain, observation_t(kind=K_MOMENT, beam=1, s=0.0_dp), &
                                 wrt, y, sy, none, nod, value, grad)
            value = -value
            grad = -grad
        else if (o%kind == K_ROOT_ROTATION) then
            call observe_station(sys, chain, observation_t(kind=K_PSI, beam=1, s=0.0_dp), wrt, &
                                 y, sy, none, nod, value, grad)
        else
            call observe_station(sys, chain, observation_t(kind=K_PSI, beam=2, s=0.0_dp), wrt, &
                                 y, sy, none, nod, value, grad)
            call observe_station(sys, chain, observation_t(kind=K_PSI, beam=1, &
                                 s=chain%length(1)), wrt, y, sy, none, nod, v1, g1)
            value = value - v1
            grad = grad - g1
        end if
    end subroutine observe_encoder

    !> The observations computed at the root or the elbow from the stations
    !! (observe_encoder): the encoders and the hub torque.
    pure logical function root_kind(k)
        integer, intent(in) :: k
        root_kind = k == K_ELBOW_ROTATION .or. k == K_ROOT_ROTATION .or. k == K_HUB_TORQUE
    end function root_kind

    !> The release family's observe at a station (beam b, arc length s from
    !! its root) from the full state y and its sensitivities sy (nstate x
    !! size(wrt)), interpolated with the element's Hermite functions (Eq.
    !! 76): position x = S + u, y = w (S the undeformed arc position), the
    !! tangent angle psi = atan2(w', 1 + u'), the curvature kappa = chi /
    !! ((1 + u')^2 + w'^2)^(3/2) with chi = w''(1 + u') - w' u'' (Eq. 72),
    !! the moment EI chi + C chi^3, the gauge strain e + kappa t/2 (e the
    !! Green axial strain, Eq. 70; t = thick<b> of the beam, d/dt = kappa/2; the gauge on the
    !! clockwise side, stretched by a counter-clockwise bend), and the
    !! velocity and acceleration of the material point along the tangent t =
    !! (1 + u', w')/|.| and the normal n = (-w', 1 + u')/|.| (a = the rates
    !! f of the state, da their sensitivities). Lengths carry no derivative
    !! here (the release family has none, beamid_release).
    pure subroutine observe_station(sys, chain, o, wrt, y, sy, a, da, value, grad, hub)
        type(dyn_system_t), intent(in) :: sys
        type(chain_t), intent(in) :: chain
        type(observation_t), intent(in) :: o
        integer, intent(in) :: wrt(:)
        real(dp), intent(in) :: y(:), sy(:, :), a(:), da(:, :)
        real(dp), intent(out) :: value, grad(:)
        !> the hub's rate and angular acceleration (Omega, Omega') of a
        !! prescribed hub rotation: velocities and accelerations are then the
        !! inertial ones (what a sensor on the arm reads), in the hub frame's
        !! components, v + Omega J rho and a + 2 Omega J v + Omega' J rho -
        !! Omega^2 rho (rho = (S + u, w); the fit's parameters leave Omega alone)
        real(dp), intent(in), optional :: hub(2)
        real(dp) :: f(4), f1(4), f2(4), h, zeta, u, w, u1, w1, u2, w2, r2, chi, kap, e, p1
        real(dp) :: vu, vw, ca, sb, om, omd, xs, gu, gw
        real(dp), dimension(size(grad)) :: du, dw, du1, dw1, du2, dw2, dr2, dchi, dkap, dvu, &
                                           dvw, dau, dgu, dgw
        real(dp) :: qe(8), ve(8), ae(8)
        real(dp) :: dqe(8, size(grad)), dve(8, size(grad)), dae(8, size(grad))
        integer :: el, first, nel_b, j, m, n, idx
        n = sys%n
        value = 0.0_dp
        grad = 0.0_dp
        first = findloc(sys%mesh%beam, o%beam, 1)
        nel_b = count(sys%mesh%beam == o%beam)
        if (first == 0) return
        h = sys%mesh%h(first)
        idx = min(max(int(o%s/h), 0), nel_b - 1)
        el = first + idx
        zeta = min(max(o%s/h - real(idx, dp), 0.0_dp), 1.0_dp)
        call fe_hermite(zeta, h, f, f1, f2)
        qe = 0.0_dp
        ve = 0.0_dp
        ae = 0.0_dp
        dqe = 0.0_dp
        dve = 0.0_dp
        dae = 0.0_dp
        do m = 1, 8
            j = sys%mesh%el_free(m, el)
            if (j == 0) cycle
            qe(m) = y(j)
            ve(m) = y(n + j)
            if (size(a) >= 2*n) ae(m) = a(n + j)
            if (size(grad) > 0) then
                dqe(m, :) = sy(j, :)
                dve(m, :) = sy(n + j, :)
                if (size(da, 1) >= 2*n) dae(m, :) = da(n + j, :)
            end if
        end do
        u = dot_product(f, qe(FE_U))
        w = dot_product(f, qe(FE_W))
        u1 = dot_product(f1, qe(FE_U))
        w1 = dot_product(f1, qe(FE_W))
        u2 = dot_product(f2, qe(FE_U))
        w2 = dot_product(f2, qe(FE_W))
        du = matmul(f, dqe(FE_U, :))
        dw = matmul(f, dqe(FE_W, :))
        du1 = matmul(f1, dqe(FE_U, :))
        dw1 = matmul(f1, dqe(FE_W, :))
        du2 = matmul(f2, dqe(FE_U, :))
        dw2 = matmul(f2, dqe(FE_W, :))
        p1 = 1.0_dp + u1
        r2 = p1*p1 + w1*w1
        dr2 = 2.0_dp*(p1*du1 + w1*dw1)
        chi = w2*p1 - w1*u2
        dchi = dw2*p1 + w2*du1 - dw1*u2 - w1*du2
        kap = chi/r2**1.5_dp
        dkap = dchi/r2**1.5_dp - 1.5_dp*chi/r2**2.5_dp*dr2
        select case (o%kind)
        case (K_X)
            value = sum(chain%length(1:o%beam - 1)) + o%s + u
            grad = du
        case (K_Y)
            value = w
            grad = dw
        case (K_PSI)
            value = atan2(w1, p1)
            grad = (p1*dw1 - w1*du1)/r2
        case (K_CURVATURE)
            value = kap
            grad = dkap
        case (K_MOMENT)
            associate (ei => chain%ei(o%beam), c => chain%cubic(o%beam))
                value = ei*chi + c*chi**3
                grad = (ei + 3.0_dp*c*chi*chi)*dchi
                do j = 1, size(wrt)
                    if (wrt(j) == param_index_beam(chain%nbeams, o%beam, IB_EI)) &
                        grad(j) = grad(j) + chi
                    if (wrt(j) == param_index_beam(chain%nbeams, o%beam, IB_C)) &
                        grad(j) = grad(j) + chi**3
                end do
            end associate
        case (K_STRAIN)
            e = u1 + 0.5_dp*(u1*u1 + w1*w1)
            associate (t => chain%thickness(o%beam))
                value = e + 0.5_dp*t*kap
                grad = p1*du1 + w1*dw1 + 0.5_dp*t*dkap
                do j = 1, size(wrt)
                    if (wrt(j) == param_index_thickness(chain%nbeams, o%beam)) &
                        grad(j) = grad(j) + 0.5_dp*kap
                end do
            end associate
        case (K_VEL_T, K_VEL_N, K_ACCEL_T, K_ACCEL_N)
            if (o%kind == K_VEL_T .or. o%kind == K_VEL_N) then
                vu = dot_product(f, ve(FE_U))
                vw = dot_product(f, ve(FE_W))
                dvu = matmul(f, dve(FE_U, :))
                dvw = matmul(f, dve(FE_W, :))
            else
                vu = dot_product(f, ae(FE_U))
                vw = dot_product(f, ae(FE_W))
                dvu = matmul(f, dae(FE_U, :))
                dvw = matmul(f, dae(FE_W, :))
            end if
            if (present(hub)) then
                ! the inertial velocity or acceleration, in the hub frame's components
                if (any(hub /= 0.0_dp)) then
                    om = hub(1)
                    omd = hub(2)
                    xs = sum(chain%length(1:o%beam - 1)) + o%s + u
                    if (o%kind == K_VEL_T .or. o%kind == K_VEL_N) then
                        vu = vu - om*w
                        vw = vw + om*xs
                        dvu = dvu - om*dw
                        dvw = dvw + om*du
                    else
                        gu = dot_product(f, ve(FE_U))
                        gw = dot_product(f, ve(FE_W))
                        dgu = matmul(f, dve(FE_U, :))
                        dgw = matmul(f, dve(FE_W, :))
                        vu = vu - 2.0_dp*om*gw - omd*w - om*om*xs
                        vw = vw + 2.0_dp*om*gu + omd*xs - om*om*w
                        dvu = dvu - 2.0_dp*om*dgw - omd*dw - om*om*du
                        dvw = dvw + 2.0_dp*om*dgu + omd*du - om*om*dw
                    end if
                end if
            end if
            if (o%kind == K_VEL_T .or. o%kind == K_ACCEL_T) then
                ca = p1*vu + w1*vw
                dau = du1*vu + p1*dvu + dw1*vw + w1*dvw
            else
                ca = -w1*vu + p1*vw
                dau = -dw1*vu - w1*dvu + du1*vw + p1*dvw
            end if
            sb = sqrt(r2)
            value = ca/sb
            grad = dau/sb - 0.5_dp*ca/(sb*r2)*dr2
        end select
    end subroutine observe_station

    !> (Omega, Omega') of the prescribed hub rotation of `sys` at t (0 without one).
    pure function hub_rates(sys, t) result(r)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t
        real(dp) :: r(2)
        integer :: l
        r = 0.0_dp
        do l = 1, sys%nloads
            select type (h => sys%loads(l)%f)
            type is (hub_forcing_t)
                call h%rate(t, r(1), r(2))
            end select
        end do
    end function hub_rates

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
        integer, allocatable :: wrt_e(:)
        type(release_exp_t) :: rough
        integer :: e, i, k, nobs
        logical :: rates
        predictions = 0.0_dp
        jacobian = 0.0_dp
        if (.not. allocated(self%cache)) allocate (self%cache(size(self%exps)))
        if (.not. allocated(self%shift)) allocate (self%shift(size(self%exps)), source=0.0_dp)
        if (.not. allocated(self%row_rate)) allocate (self%row_rate(size(self%row_exp)))
        self%row_rate = 0.0_dp
        rates = self%want_rates
        if (.not. allocated(self%v0)) allocate (self%v0(size(self%exps)), source=0.0_dp)
        if (.not. allocated(self%v0_fit)) allocate (self%v0_fit(size(self%exps)), &
                                                    source=.false.)
        if (allocated(self%row_dv0)) deallocate (self%row_dv0)
        allocate (self%row_dv0(size(self%row_exp)), source=0.0_dp)
        ! the model time of every row: its record time plus its record's offset
        tm = max(0.0_dp, self%row_t + self%shift(self%row_exp))
        do e = 1, size(self%exps)
            if (.not. any(self%row_exp == e)) cycle
            times = distinct_sorted(pack(tm, self%row_exp == e))
            nobs = size(self%eobs(e)%o)
            ! the initial velocity (the chain's nuisance v0) and its column
            self%exps(e)%v0 = self%v0(e)
            if (self%v0_fit(e)) then
                wrt_e = [wrt, WRT_V0]
            else
                wrt_e = wrt
            end if
            allocate (y(nobs, size(times)), dy(nobs, size(times), size(wrt_e)), &
                      rate(nobs, size(times)), source=0.0_dp)
            if (self%rough == ROUGH_ALL .and. rough_tolerance(self%exps(e)) > 0.0_dp) then
                rough = self%exps(e)
                rough%rtol = rough_tolerance(rough)
                if (rates) then
                    call release_response(self%nbeams, params, rough, times, wrt_e, &
                                          self%eobs(e)%o, y, dy, stat, rate)
                else
                    call release_response(self%nbeams, params, rough, times, wrt_e, &
                                          self%eobs(e)%o, y, dy, stat)
                end if
            else if (self%rough == ROUGH_JACOBIAN .and. size(wrt_e) > 0 .and. &
                     rough_tolerance(self%exps(e)) > 0.0_dp) then
                call rough_response(e, times, y, dy, rate)
            else
                if (rates) then
                    call release_response(self%nbeams, params, self%exps(e), times, wrt_e, &
                                          self%eobs(e)%o, y, dy, stat, rate)
                else
                    call release_response(self%nbeams, params, self%exps(e), times, wrt_e, &
                                          self%eobs(e)%o, y, dy, stat)
                end if
                if (stat%code == STATUS_OK .and. size(wrt_e) == 0) call remember(e, times, y, rate)
            end if
            if (stat%code /= STATUS_OK) then
                stat%message = trim(stat%message)//' (experiment '//fmt_int(e)//')'
                return
            end if
            do i = 1, size(self%row_exp)
                if (self%row_exp(i) /= e) cycle
                k = sorted_index(times, tm(i))
                predictions(i) = y(self%row_oi(i), k)
                jacobian(i, :) = dy(self%row_oi(i), k, 1:size(wrt))
                if (self%v0_fit(e)) self%row_dv0(i) = dy(self%row_oi(i), k, size(wrt_e))
                ! before the release (model time clipped at 0) the chain rests
                if (self%row_t(i) + self%shift(e) > 0.0_dp) &
                    self%row_rate(i) = rate(self%row_oi(i), k)
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
            ! the cache's key: the model's parameters and the initial velocity
            if (cached) cached = size(self%cache(e)%times) == size(times) .and. &
                                 size(self%cache(e)%params) == size(params) + 1
            if (cached) cached = all(self%cache(e)%params == [params, self%v0(e)]) .and. &
                                 all(self%cache(e)%times == times) .and. &
                                 (allocated(self%cache(e)%rate) .or. .not. rates)
            rate = 0.0_dp
            if (cached) then
                y = self%cache(e)%y
                if (rates) rate = self%cache(e)%rate
            else
                allocate (none(size(self%eobs(e)%o), size(times), 0))
                if (rates) then
                    call release_response(self%nbeams, params, self%exps(e), times, wrt_e(1:0), &
                                          self%eobs(e)%o, y, none, stat, rate)
                else
                    call release_response(self%nbeams, params, self%exps(e), times, wrt_e(1:0), &
                                          self%eobs(e)%o, y, none, stat)
                end if
                if (stat%code /= STATUS_OK) return
                call remember(e, times, y, rate)
            end if
            rough = self%exps(e)
            rough%rtol = rough_tolerance(rough)
            allocate (yr(size(self%eobs(e)%o), size(times)))
            call release_response(self%nbeams, params, rough, times, wrt_e, self%eobs(e)%o, yr, &
                                  dy, stat)
        end subroutine rough_response

        subroutine remember(e, times, y, rate)
            integer, intent(in) :: e
            real(dp), intent(in) :: times(:), y(:, :), rate(:, :)
            self%cache(e)%valid = .true.
            self%cache(e)%params = [params, self%v0(e)]
            self%cache(e)%times = times
            self%cache(e)%y = y
            if (rates) then
                self%cache(e)%rate = rate
            else if (allocated(self%cache(e)%rate)) then
                deallocate (self%cache(e)%rate)
            end if
        end subroutine remember
    end subroutine dynamic_evaluate

    !> The index of x in the ascending distinct values `sorted` (which hold
    !! it): a bisection, so that finding each row's output time costs
    !! O(log n) on a long record, not O(n) (findloc: quadratic in the rows).
    pure integer function sorted_index(sorted, x) result(k)
        real(dp), intent(in) :: sorted(:), x
        integer :: lo, hi, mid
        lo = 1
        hi = size(sorted)
        do while (lo < hi)
            mid = (lo + hi)/2
            if (sorted(mid) < x) then
                lo = mid + 1
            else
                hi = mid
            end if
        end do
        k = lo
    end function sorted_index
end module beamid_dynamic_experiments
