!> Static experiments for the estimation machinery (Section 3.2).
!!
!! An experiment is a static load case (a fixed-direction tip force and
!! moment, or a radial wire); a data row is (experiment, quantity, value,
!! sigma). Predictions and their sensitivities come from the arc-length
!! solver (`solve_static`: outputs and IFT sensitivities, Eq. 40-51), so the
!! Jacobian columns of Eq. 52 and 56 are available for any named parameter.
!!
!! Observations (beamid_observations, the one table): x_tip y_tip tip_angle
!! wire_force x_elbow y_elbow, u_tip = x_tip - (L1 + ... + Ln) and w_tip =
!! y_tip; each row holds its observation (kind and locus) and `observe`
!! computes it and its sensitivities from a static solution.
!!
!! The candidate effects, the physical bounds of every parameter and their
!! null values are the table of beamid_effects.
module beamid_static_experiments
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, STATUS_OK, ERR_INPUT, fmt_int
    use beamid_model, only: chain_t, chain_from_vector, param_index_beam, param_index_thickness, &
                            IB_L, IB_C, IB_EI
    use beamid_arclength, only: static_load_t, static_options_t, static_solution_t, &
                                solve_static, static_stations, LOAD_TIP, LOAD_WIRE, OUT_X_TIP, &
                                OUT_Y_TIP, &
                                OUT_TIP_ANGLE, OUT_WIRE_FORCE, OUT_X_ELBOW, OUT_Y_ELBOW
    use beamid_observations, only: observation_t, obs_label, observation_why_not, probe_kinds, &
                                   KINDS, FAM_STATIC, why_detail, WHY_OK, WHY_WIRE, WHY_MOTOR, WHY_FAMILY, &
                                   K_X_TIP, K_Y_TIP, K_TIP_ANGLE, K_WIRE_FORCE, K_X_ELBOW, &
                                   K_Y_ELBOW, K_U_TIP, K_W_TIP, K_MOTOR_TORQUE, LOCUS_STATION, &
                                   K_X, K_Y, K_PSI, K_CURVATURE, K_MOMENT, K_STRAIN, &
                                   K_ELBOW_ROTATION, K_ROOT_ROTATION, &
                                   K_REACTION_X, K_REACTION_Y, K_REACTION_MOMENT
    use beamid_estimation, only: residual_model_t, sort_desc
    use beamid_family, only: experiment_family_t, family_input_t, EV_FX, EV_FY, EV_MOMENT, &
                             EV_WIRE_LENGTH
    implicit none
    private

    public :: static_experiments_t, static_experiments_init, observe
    public :: probe_rows, median_of, distinct_sorted

    !> Static experiments and the data rows they predict: the static family
    !! of the inverse problem (experiment kinds EXP_TIP, EXP_WIRE).
    type, extends(experiment_family_t) :: static_experiments_t
        type(static_load_t), allocatable :: loads(:)
        type(static_options_t) :: opts
    contains
        procedure :: evaluate => static_evaluate
        procedure :: build => static_build
        procedure :: probe => static_probe
        procedure :: probe_model => static_probe_model
    end type static_experiments_t

contains

    !> The family's constructor for the problem: a static load per
    !! experiment from its spec (keys EV_FX, EV_FY, EV_MOMENT,
    !! EV_WIRE_LENGTH), then static_experiments_init.
    subroutine static_build(self, input, stat)
        class(static_experiments_t), intent(inout) :: self
        type(family_input_t), intent(in) :: input
        type(status_t), intent(inout) :: stat
        type(static_load_t), allocatable :: loads(:)
        integer :: e
        allocate (loads(size(input%kinds)))
        do e = 1, size(input%kinds)
            associate (v => input%specs(e))
                loads(e) = static_load_t(kind=input%kinds(e), fx=v%get(EV_FX), fy=v%get(EV_FY), &
                                         moment=v%get(EV_MOMENT), &
                                         wire_length=v%get(EV_WIRE_LENGTH))
            end associate
        end do
        call static_experiments_init(input%nbeams, loads, input%row_exp, input%row_obs, &
                                     input%tol, self, stat)
        self%plain_trials = .false.
        self%rough_jacobian_ok = .false.
    end subroutine static_build

    !> Probe rows: every static experiment and every quantity it can
    !! measure (probe_rows), with the median sigma of the data rows.
    subroutine static_probe(self, sigma, plocal, pq, psig)
        class(static_experiments_t), intent(in) :: self
        real(dp), intent(in) :: sigma(:)
        integer, allocatable, intent(out) :: plocal(:), pq(:)
        real(dp), allocatable, intent(out) :: psig(:)
        integer, allocatable :: row_kinds(:)
        ! the rows' kinds as a contiguous copy (a component of an array of
        ! types is strided: passing it made an array temporary each call)
        row_kinds = self%row_obs%kind
        call probe_rows(self%loads, row_kinds, sigma, plocal, pq, psig)
    end subroutine static_probe

    !> The static experiments of the probe rows (local experiments plocal,
    !! kinds pq) as a model of their own.
    subroutine static_probe_model(self, plocal, pq, tol, model, stat)
        class(static_experiments_t), intent(in) :: self
        integer, intent(in) :: plocal(:), pq(:)
        real(dp), intent(in) :: tol
        class(residual_model_t), allocatable, intent(inout) :: model
        type(status_t), intent(inout) :: stat
        type(static_experiments_t) :: probe
        integer :: i
        if (allocated(model)) deallocate (model)
        call static_experiments_init(self%nbeams, self%loads, plocal, &
                                     [(observation_t(kind=pq(i)), i=1, size(pq))], tol, probe, &
                                     stat)
        if (stat%code /= STATUS_OK) return
        allocate (model, source=probe)
    end subroutine static_probe_model

    !> Set up and validate the experiments and rows (the list lengths and
    !! experiment numbers as inverse_problem_init checked them).
    pure subroutine static_experiments_init(nbeams, loads, row_exp, row_obs, tol, self, stat)
        integer, intent(in) :: nbeams
        type(static_load_t), intent(in) :: loads(:)
        integer, intent(in) :: row_exp(:)
        type(observation_t), intent(in) :: row_obs(:)
        real(dp), intent(in) :: tol
        type(static_experiments_t), intent(out) :: self
        type(status_t), intent(inout) :: stat
        integer :: i, reason
        character(len=:), allocatable :: problem, detail
        problem = ''
        do i = 1, size(row_exp)
            reason = observation_why_not(row_obs(i), FAM_STATIC, &
                                         loads(row_exp(i))%kind == LOAD_WIRE, .false., nbeams, &
                                         [real(dp) ::])
            detail = why_detail(row_obs(i), reason, FAM_STATIC, nbeams, [real(dp) ::])
            select case (reason)
            case (WHY_OK)
            case (WHY_WIRE)
                problem = ': '//obs_label(row_obs(i))//' measured in experiment '// &
                          fmt_int(row_exp(i))//', which has no wire'
            case (WHY_MOTOR)
                problem = ': '//obs_label(row_obs(i))//' measured in the static experiment '// &
                          fmt_int(row_exp(i))//', which has no motor'
            case (WHY_FAMILY)
                if (row_obs(i)%kind == K_MOTOR_TORQUE) then
                    problem = ': motor_torque measured in the static experiment '// &
                              fmt_int(row_exp(i))//', which has no motor'
                else
                    problem = ': '//obs_label(row_obs(i))//' in the static experiment '// &
                              fmt_int(row_exp(i))//': '//detail
                end if
            case default
                problem = ': '//detail
            end select
            if (len(problem) > 0) then
                call set_status(stat, ERR_INPUT, 'static experiments', 'row '//fmt_int(i)// &
                                problem)
                return
            end if
        end do
        self%nbeams = nbeams
        self%loads = loads
        self%row_exp = row_exp
        self%row_obs = row_obs
        if (tol > 0.0_dp) self%opts%tol = tol
    end subroutine static_experiments_init

    !> Predictions and sensitivities of the rows: one static solve per
    !! experiment that has rows (Eq. 52, 56).
    subroutine static_evaluate(self, params, wrt, predictions, jacobian, stat)
        class(static_experiments_t), intent(inout) :: self
        real(dp), intent(in) :: params(:)
        integer, intent(in) :: wrt(:)
        real(dp), intent(out) :: predictions(:)
        real(dp), intent(out) :: jacobian(:, :)
        type(status_t), intent(inout) :: stat
        type(chain_t) :: chain
        type(static_solution_t) :: sol
        integer :: e, i, k, nb
        integer, allocatable :: st(:)
        real(dp), allocatable :: z(:, :), dz(:, :, :)
        predictions = 0.0_dp
        jacobian = 0.0_dp
        nb = self%nbeams
        call chain_from_vector(nb, params, chain, stat)
        if (stat%code /= STATUS_OK) return
        do e = 1, size(self%loads)
            if (.not. any(self%row_exp == e)) cycle
            call solve_static(chain, self%loads(e), wrt, self%opts, sol, stat)
            if (stat%code /= STATUS_OK) then
                stat%message = trim(stat%message)//' (experiment '//fmt_int(e)//')'
                return
            end if
            ! the station rows of this experiment: one more shot for all
            st = pack([(i, i=1, size(self%row_exp))], self%row_exp == e .and. &
                      [(KINDS(self%row_obs(i)%kind)%locus == LOCUS_STATION, &
                        i=1, size(self%row_exp))])
            if (size(st) > 0) then
                allocate (z(6, size(st)), dz(6, size(st), size(wrt)))
                call static_stations(chain, self%loads(e), sol, wrt, self%opts, &
                                     self%row_obs(st)%beam, self%row_obs(st)%s, z, dz, stat)
                if (stat%code /= STATUS_OK) then
                    stat%message = trim(stat%message)//' (experiment '//fmt_int(e)//')'
                    return
                end if
                do k = 1, size(st)
                    call observe_station(chain, self%row_obs(st(k)), wrt, z(:, k), dz(:, k, :), &
                                         predictions(st(k)), jacobian(st(k), :))
                end do
                deallocate (z, dz)
            end if
            ! encoders (psi at the clamp, and across the elbow) and the
            ! clamp's load cell: the states at the clamp and either side of
            ! the elbow
            st = pack([(i, i=1, size(self%row_exp))], self%row_exp == e .and. &
                      at_joint(self%row_obs%kind))
            if (size(st) > 0) then
                allocate (z(6, 3), dz(6, 3, size(wrt)))
                call static_stations(chain, self%loads(e), sol, wrt, self%opts, &
                                     [1, 1, min(2, nb)], [0.0_dp, chain%length(1), 0.0_dp], &
                                     z, dz, stat)
                if (stat%code /= STATUS_OK) then
                    stat%message = trim(stat%message)//' (experiment '//fmt_int(e)//')'
                    return
                end if
                do k = 1, size(st)
                    if (self%row_obs(st(k))%kind == K_ROOT_ROTATION) then
                        predictions(st(k)) = z(3, 1)
                        jacobian(st(k), :) = dz(3, 1, :)
                    else if (self%row_obs(st(k))%kind /= K_ELBOW_ROTATION) then
                        call observe_reaction(chain, self%row_obs(st(k))%kind, wrt, z(:, 1), &
                                              dz(:, 1, :), predictions(st(k)), &
                                              jacobian(st(k), :))
                    else
                        ! psi after the joint minus psi before it; the station
                        ! before it is a material point, the joint moves with L1
                        predictions(st(k)) = z(3, 3) - z(3, 2)
                        jacobian(st(k), :) = dz(3, 3, :) - dz(3, 2, :)
                        where (wrt == param_index_beam(nb, 1, IB_L)) &
                            jacobian(st(k), :) = jacobian(st(k), :) - z(4, 2)
                    end if
                end do
                deallocate (z, dz)
            end if
            do i = 1, size(self%row_exp)
                if (self%row_exp(i) /= e) cycle
                if (KINDS(self%row_obs(i)%kind)%locus == LOCUS_STATION) cycle
                if (at_joint(self%row_obs(i)%kind)) cycle
                call observe(chain, sol, self%row_obs(i), wrt, predictions(i), jacobian(i, :))
            end do
        end do
    end subroutine static_evaluate

    !> Kinds read from the states at the clamp and either side of the
    !! elbow: the encoders and the load cell.
    elemental logical function at_joint(kind)
        integer, intent(in) :: kind
        at_joint = kind == K_ROOT_ROTATION .or. kind == K_ELBOW_ROTATION .or. &
                   kind == K_REACTION_X .or. kind == K_REACTION_Y .or. &
                   kind == K_REACTION_MOMENT
    end function at_joint

    !> The clamp's load cell from the state z = (x, y, psi, k, Q, N) at
    !! the clamp (s = 0 of beam 1) and its sensitivities dz: the internal
    !! force there is N t + Q n (t = (cos psi, sin psi), n = (-sin psi, cos
    !! psi): the force the arm beyond the clamp transmits, the tip load's
    !! resultant), the internal moment M(0) = EI1 k + C1 k^3; the clamp
    !! exerts their opposites on the arm (kind: K_REACTION_X, _Y, _MOMENT).
    pure subroutine observe_reaction(chain, kind, wrt, z, dz, value, grad)
        type(chain_t), intent(in) :: chain
        integer, intent(in) :: kind
        integer, intent(in) :: wrt(:)
        real(dp), intent(in) :: z(:), dz(:, :)
        real(dp), intent(out) :: value, grad(:)
        real(dp) :: c, s
        c = cos(z(3))
        s = sin(z(3))
        select case (kind)
        case (K_REACTION_X)
            value = -(z(6)*c - z(5)*s)
            grad = -(dz(6, :)*c - dz(5, :)*s - (z(6)*s + z(5)*c)*dz(3, :))
        case (K_REACTION_Y)
            value = -(z(6)*s + z(5)*c)
            grad = -(dz(6, :)*s + dz(5, :)*c + (z(6)*c - z(5)*s)*dz(3, :))
        case default
            call observe_station(chain, observation_t(kind=K_MOMENT, beam=1, s=0.0_dp), wrt, &
                                 z, dz, value, grad)
            value = -value
            grad = -grad
        end select
    end subroutine observe_reaction

    !> The static family's observe: the value of observation o in the
    !! solution sol of `chain` and its derivatives d/d params(wrt).
    pure subroutine observe(chain, sol, o, wrt, value, grad)
        type(chain_t), intent(in) :: chain
        type(static_solution_t), intent(in) :: sol
        type(observation_t), intent(in) :: o
        integer, intent(in) :: wrt(:)
        real(dp), intent(out) :: value, grad(:)
        integer :: out, j, k, nb
        select case (o%kind)
        case (K_X_TIP, K_U_TIP)
            out = OUT_X_TIP
        case (K_Y_TIP, K_W_TIP)
            out = OUT_Y_TIP
        case (K_TIP_ANGLE)
            out = OUT_TIP_ANGLE
        case (K_WIRE_FORCE)
            out = OUT_WIRE_FORCE
        case (K_X_ELBOW)
            out = OUT_X_ELBOW
        case (K_Y_ELBOW)
            out = OUT_Y_ELBOW
        case default
            value = 0.0_dp
            grad = 0.0_dp
            return
        end select
        value = sol%outputs(out)
        grad = sol%doutputs(out, :)
        if (o%kind == K_U_TIP) then
            nb = chain%nbeams
            value = value - sum(chain%length)
            do j = 1, size(wrt)
                do k = 1, nb
                    if (wrt(j) == param_index_beam(nb, k, IB_L)) grad(j) = grad(j) - 1.0_dp
                end do
            end do
        end if
    end subroutine observe

    !> The static family's observe at a station from the arc-length state
    !! z = (x, y, psi, k, Q, N) there and its sensitivities dz (6 x
    !! size(wrt)): x, y, psi; curvature k; moment EI k + C k^3; gauge strain
    !! k t/2 on the clockwise side (the arc-length model is inextensible:
    !! no axial strain; t the strip thickness of the gauge's beam, parameter
    !! thick<beam>, d/dt = k/2).
    pure subroutine observe_station(chain, o, wrt, z, dz, value, grad)
        type(chain_t), intent(in) :: chain
        type(observation_t), intent(in) :: o
        integer, intent(in) :: wrt(:)
        real(dp), intent(in) :: z(:), dz(:, :)
        real(dp), intent(out) :: value, grad(:)
        integer :: j
        real(dp) :: k
        value = 0.0_dp
        grad = 0.0_dp
        k = z(4)
        select case (o%kind)
        case (K_X)
            value = z(1)
            grad = dz(1, :)
        case (K_Y)
            value = z(2)
            grad = dz(2, :)
        case (K_PSI)
            value = z(3)
            grad = dz(3, :)
        case (K_CURVATURE)
            value = k
            grad = dz(4, :)
        case (K_MOMENT)
            associate (ei => chain%ei(o%beam), c => chain%cubic(o%beam))
                value = ei*k + c*k**3
                grad = (ei + 3.0_dp*c*k*k)*dz(4, :)
                do j = 1, size(wrt)
                    if (wrt(j) == param_index_beam(chain%nbeams, o%beam, IB_EI)) &
                        grad(j) = grad(j) + k
                    if (wrt(j) == param_index_beam(chain%nbeams, o%beam, IB_C)) &
                        grad(j) = grad(j) + k**3
                end do
            end associate
        case (K_STRAIN)
            associate (t => chain%thickness(o%beam))
                value = 0.5_dp*t*k
                grad = 0.5_dp*t*dz(4, :)
                do j = 1, size(wrt)
                    if (wrt(j) == param_index_thickness(chain%nbeams, o%beam)) &
                        grad(j) = grad(j) + 0.5_dp*k
                end do
            end associate
        end select
    end subroutine observe_station

    !> Probe rows for separating rival explanations: every experiment and
    !! every kind of the static probe list (beamid_observations: x_tip y_tip
    !! tip_angle wire_force x_elbow y_elbow; wire_force only with a wire), with
    !! the sigma to judge a difference by: the median data sigma of that kind
    !! and its twin (u_tip for x_tip), or when neither was measured the
    !! kind's default sigma of the table. row_kind: the kind of each data row.
    pure subroutine probe_rows(loads, row_kind, sigma, pexp, pq, psig)
        type(static_load_t), intent(in) :: loads(:)
        integer, intent(in) :: row_kind(:)
        real(dp), intent(in) :: sigma(:)
        integer, allocatable, intent(out) :: pexp(:), pq(:)
        real(dp), allocatable, intent(out) :: psig(:)
        integer, allocatable :: probe_q(:)
        real(dp), allocatable :: sk(:)
        integer :: e, k, n, np
        probe_q = probe_kinds(FAM_STATIC)
        np = size(probe_q)
        allocate (sk(np))
        do k = 1, np
            sk(k) = median_of(pack(sigma, row_kind == probe_q(k) .or. &
                                   (KINDS(probe_q(k))%twin > 0 .and. &
                                    row_kind == KINDS(probe_q(k))%twin)), &
                              KINDS(probe_q(k))%sigma)
        end do
        allocate (pexp(np*size(loads)), pq(np*size(loads)), psig(np*size(loads)))
        n = 0
        do e = 1, size(loads)
            do k = 1, np
                if (observation_why_not(observation_t(kind=probe_q(k)), FAM_STATIC, &
                                        loads(e)%kind == LOAD_WIRE, .false., 1, [real(dp) ::]) &
                    /= WHY_OK) cycle
                n = n + 1
                pexp(n) = e
                pq(n) = probe_q(k)
                psig(n) = sk(k)
            end do
        end do
        pexp = pexp(:n)
        pq = pq(:n)
        psig = psig(:n)
    end subroutine probe_rows

    !> The median of x (default when x is empty).
    pure real(dp) function median_of(x, default)
        real(dp), intent(in) :: x(:), default
        real(dp) :: y(size(x))
        integer :: n
        n = size(x)
        if (n == 0) then
            median_of = default
            return
        end if
        y = x(sort_desc(-x))   ! ascending
        if (mod(n, 2) == 1) then
            median_of = y((n + 1)/2)
        else
            median_of = 0.5_dp*(y(n/2) + y(n/2 + 1))
        end if
    end function median_of

    !> The distinct values of x in ascending order (a merge sort: the
    !! output times of a long record's rows, O(n log n) in any row order).
    pure function distinct_sorted(x) result(out)
        real(dp), intent(in) :: x(:)
        real(dp), allocatable :: out(:)
        real(dp) :: v(size(x))
        integer :: i, n
        v = ascending(x)
        allocate (out(size(v)))
        n = 0
        do i = 1, size(v)
            if (n > 0) then
                if (v(i) == out(n)) cycle
            end if
            n = n + 1
            out(n) = v(i)
        end do
        out = out(:n)
    end function distinct_sorted

    !> x in ascending order: a bottom-up merge sort (runs of width 1, 2,
    !! 4, ... merged from one buffer into the other).
    pure function ascending(x) result(v)
        real(dp), intent(in) :: x(:)
        real(dp) :: v(size(x))
        real(dp) :: b(size(x))
        integer :: n, width, lo, mid, hi, i, j, k
        n = size(x)
        v = x
        width = 1
        do while (width < n)
            do lo = 1, n, 2*width
                mid = min(lo + width - 1, n)
                hi = min(lo + 2*width - 1, n)
                i = lo
                j = mid + 1
                do k = lo, hi
                    if (j > hi) then
                        b(k) = v(i)
                        i = i + 1
                    else if (i > mid) then
                        b(k) = v(j)
                        j = j + 1
                    else if (v(j) < v(i)) then
                        b(k) = v(j)
                        j = j + 1
                    else
                        b(k) = v(i)
                        i = i + 1
                    end if
                end do
            end do
            v = b
            width = 2*width
        end do
    end function ascending
end module beamid_static_experiments
