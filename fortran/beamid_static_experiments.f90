!> Static experiments for the estimation machinery (Section 3.2).
!!
!! An experiment is a static load case (a fixed-direction tip force and
!! moment, or a radial wire); a data row is (experiment, quantity, value,
!! sigma). Predictions and their sensitivities come from the arc-length
!! solver (`solve_static`: outputs and IFT sensitivities, Eq. 40-51), so the
!! Jacobian columns of Eq. 52 and 56 are available for any named parameter.
!!
!! Quantities (codes Q_*): x_tip y_tip tip_angle wire_force x_elbow y_elbow,
!! u_tip = x_tip - (L1 + ... + Ln) and w_tip = y_tip.
!!
!! The candidate effects, the physical bounds of every parameter and their
!! null values are the table of beamid_effects.
module beamid_static_experiments
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, STATUS_OK, ERR_INPUT, fmt_int
    use beamid_model, only: chain_t, chain_from_vector, param_index_beam, IB_L
    use beamid_arclength, only: static_load_t, static_options_t, static_solution_t, &
                                solve_static, LOAD_TIP, LOAD_WIRE, OUT_X_TIP, OUT_Y_TIP, &
                                OUT_TIP_ANGLE, OUT_WIRE_FORCE, OUT_X_ELBOW, OUT_Y_ELBOW
    use beamid_estimation, only: residual_model_t, sort_desc
    implicit none
    private

    public :: static_experiments_t, static_experiments_init, quantity_code, quantity_label
    public :: probe_rows, NQUANT, median_of, distinct_sorted

    !> Quantity codes.
    integer, parameter, public :: Q_X_TIP = 1, Q_Y_TIP = 2, Q_TIP_ANGLE = 3, &
                                  Q_WIRE_FORCE = 4, Q_X_ELBOW = 5, Q_Y_ELBOW = 6, Q_U_TIP = 7, &
                                  Q_W_TIP = 8, Q_MOTOR_TORQUE = 9
    !> The one quantity registry of every experiment family: static
    !! experiments measure codes 1-8 (wire_force with a wire only), release
    !! experiments (beamid_dynamic_experiments) all but wire_force, and
    !! motor_torque only with a motor.
    integer, parameter :: NQUANT = 9
    character(len=*), parameter :: QUANTITY_NAMES(NQUANT) = [character(len=12) :: &
        'x_tip', 'y_tip', 'tip_angle', 'wire_force', 'x_elbow', 'y_elbow', 'u_tip', 'w_tip', &
        'motor_torque']
    !> Solver output feeding each static quantity (motor_torque: none).
    integer, parameter :: QUANTITY_OUTPUT(NQUANT) = [OUT_X_TIP, OUT_Y_TIP, OUT_TIP_ANGLE, &
        OUT_WIRE_FORCE, OUT_X_ELBOW, OUT_Y_ELBOW, OUT_X_TIP, OUT_Y_TIP, 0]

    !> Static experiments and the data rows they predict.
    type, extends(residual_model_t) :: static_experiments_t
        integer :: nbeams = 0
        type(static_load_t), allocatable :: loads(:)
        integer, allocatable :: row_exp(:)      !< experiment of each row
        integer, allocatable :: row_quantity(:) !< Q_* code of each row
        type(static_options_t) :: opts
    contains
        procedure :: evaluate => static_evaluate
    end type static_experiments_t

contains

    !> Code of a quantity name (0 when unknown).
    pure integer function quantity_code(name)
        character(len=*), intent(in) :: name
        integer :: i
        quantity_code = 0
        do i = 1, NQUANT
            if (trim(adjustl(name)) == trim(QUANTITY_NAMES(i))) quantity_code = i
        end do
    end function quantity_code

    pure function quantity_label(code) result(name)
        integer, intent(in) :: code
        character(len=:), allocatable :: name
        if (code >= 1 .and. code <= NQUANT) then
            name = trim(QUANTITY_NAMES(code))
        else
            name = '?'
        end if
    end function quantity_label

    !> Set up and validate the experiments and rows (the list lengths and
    !! experiment numbers as inverse_problem_init checked them).
    pure subroutine static_experiments_init(nbeams, loads, row_exp, row_quantity, tol, &
                                            self, stat)
        integer, intent(in) :: nbeams
        type(static_load_t), intent(in) :: loads(:)
        integer, intent(in) :: row_exp(:), row_quantity(:)
        real(dp), intent(in) :: tol
        type(static_experiments_t), intent(out) :: self
        type(status_t), intent(inout) :: stat
        integer :: i
        character(len=:), allocatable :: problem
        problem = ''
        do i = 1, size(row_exp)
            if (row_quantity(i) < 1 .or. row_quantity(i) > NQUANT) then
                problem = ' has quantity code '//fmt_int(row_quantity(i))//', expected 1..'// &
                          fmt_int(NQUANT)
            else if (row_quantity(i) == Q_WIRE_FORCE .and. &
                     loads(row_exp(i))%kind /= LOAD_WIRE) then
                problem = ': wire_force measured in experiment '//fmt_int(row_exp(i))// &
                          ', which has no wire'
            else if (row_quantity(i) == Q_MOTOR_TORQUE) then
                problem = ': motor_torque measured in the static experiment '// &
                          fmt_int(row_exp(i))//', which has no motor'
            end if
            if (len(problem) > 0) then
                call set_status(stat, ERR_INPUT, 'static experiments', 'row '//fmt_int(i)// &
                                problem)
                return
            end if
        end do
        self%nbeams = nbeams
        self%loads = loads
        self%row_exp = row_exp
        self%row_quantity = row_quantity
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
        integer :: e, i, j, q, k, nb
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
            do i = 1, size(self%row_exp)
                if (self%row_exp(i) /= e) cycle
                q = self%row_quantity(i)
                predictions(i) = sol%outputs(QUANTITY_OUTPUT(q))
                jacobian(i, :) = sol%doutputs(QUANTITY_OUTPUT(q), :)
                if (q == Q_U_TIP) then
                    predictions(i) = predictions(i) - sum(chain%length)
                    do j = 1, size(wrt)
                        do k = 1, nb
                            if (wrt(j) == param_index_beam(nb, k, IB_L)) &
                                jacobian(i, j) = jacobian(i, j) - 1.0_dp
                        end do
                    end do
                end if
            end do
        end do
    end subroutine static_evaluate

    !> Probe rows for separating rival explanations: every experiment and
    !! every quantity it can measure (wire_force only with a wire), with the
    !! sigma to judge a difference by: the median data sigma of that quantity,
    !! or when it was not measured the defaults 1e-3 m, 1e-3 rad, 0.1 N.
    pure subroutine probe_rows(loads, row_quantity, sigma, pexp, pq, psig)
        type(static_load_t), intent(in) :: loads(:)
        integer, intent(in) :: row_quantity(:)
        real(dp), intent(in) :: sigma(:)
        integer, allocatable, intent(out) :: pexp(:), pq(:)
        real(dp), allocatable, intent(out) :: psig(:)
        integer, parameter :: probe_q(6) = [Q_X_TIP, Q_Y_TIP, Q_TIP_ANGLE, Q_WIRE_FORCE, &
                                            Q_X_ELBOW, Q_Y_ELBOW]
        real(dp), parameter :: default_sigma(6) = [1.0e-3_dp, 1.0e-3_dp, 1.0e-3_dp, 0.1_dp, &
                                                   1.0e-3_dp, 1.0e-3_dp]
        integer :: e, k, n
        real(dp) :: sk(6)
        do k = 1, 6
            sk(k) = median_of(pack(sigma, row_quantity == probe_q(k) .or. &
                                   (probe_q(k) == Q_X_TIP .and. row_quantity == Q_U_TIP) .or. &
                                   (probe_q(k) == Q_Y_TIP .and. row_quantity == Q_W_TIP)), &
                              default_sigma(k))
        end do
        allocate (pexp(6*size(loads)), pq(6*size(loads)), psig(6*size(loads)))
        n = 0
        do e = 1, size(loads)
            do k = 1, 6
                if (probe_q(k) == Q_WIRE_FORCE .and. loads(e)%kind /= LOAD_WIRE) cycle
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

    !> The distinct values of x in ascending order.
    pure function distinct_sorted(x) result(out)
        real(dp), intent(in) :: x(:)
        real(dp), allocatable :: out(:)
        real(dp) :: v(size(x))
        integer :: i, n
        v = x(sort_desc(-x))   ! ascending
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
end module beamid_static_experiments
