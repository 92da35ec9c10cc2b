!> Four problems of the NIST Statistical Reference Datasets (StRD) for
!! nonlinear regression, with their certified values: the data, both NIST
!! starting points, the certified estimates and standard deviations and the
!! residual sum of squares, as published (12-11 significant digits) at
!! https://www.itl.nist.gov/div898/strd/nls/nls_main.shtml, files
!! Misra1a.dat (lower difficulty), BoxBOD.dat, MGH09.dat and Thurber.dat
!! (higher difficulty). Typed in from those files; nothing here is computed.
!! `nist_model_t` is their model class as an experiment family of
!! beamid_estimation (predictions and the analytic Jacobian).
!!
!! The certified standard deviations are NIST's: s sqrt(diag((J^T J)^-1)) at
!! the certified estimates, s^2 = RSS / (n - p), the data unweighted.
module nist_strd_data
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, STATUS_OK, ERR_NUMERIC
    use beamid_estimation, only: residual_model_t
    implicit none
    private

    public :: nist_problem_t, nist_problems, nist_model_t
    public :: MODEL_EXP_RISE, MODEL_RATIONAL_12, MODEL_RATIONAL_33

    !> Model classes of the problems below.
    !! MODEL_EXP_RISE:    y = b1 (1 - exp(-b2 x))                 (Misra1a, BoxBOD)
    !! MODEL_RATIONAL_12: y = b1 (x^2 + x b2) / (x^2 + x b3 + b4)  (MGH09)
    !! MODEL_RATIONAL_33: y = (b1 + b2 x + b3 x^2 + b4 x^3)
    !!                        / (1 + b5 x + b6 x^2 + b7 x^3)        (Thurber)
    integer, parameter :: MODEL_EXP_RISE = 1, MODEL_RATIONAL_12 = 2, MODEL_RATIONAL_33 = 3
    !> A denominator outside these magnitudes is not evaluated (its square
    !! enters the Jacobian).
    real(dp), parameter :: TINY_DEN = 1.0e-150_dp, HUGE_DEN = 1.0e150_dp
    !> Predictions beyond this are not evaluated (nist_evaluate).
    real(dp), parameter :: HUGE_PRED = 1.0e100_dp

    !> One certified problem.
    type :: nist_problem_t
        character(len=:), allocatable :: name
        integer :: model = 0
        real(dp), allocatable :: x(:), y(:)
        real(dp), allocatable :: start1(:), start2(:)
        real(dp), allocatable :: b(:), sd(:)   !< certified estimates, standard deviations
        real(dp) :: rss = 0.0_dp               !< certified residual sum of squares
    end type nist_problem_t

    !> A NIST model as an experiment family: its predictions and analytic
    !! Jacobian at the predictor values x.
    type, extends(residual_model_t) :: nist_model_t
        integer :: model = 0
        real(dp), allocatable :: x(:)
        integer :: evaluations = 0
    contains
        procedure :: evaluate => nist_evaluate
    end type nist_model_t

contains

    subroutine nist_evaluate(self, params, wrt, predictions, jacobian, stat)
        class(nist_model_t), intent(inout) :: self
        real(dp), intent(in) :: params(:)
        integer, intent(in) :: wrt(:)
        real(dp), intent(out) :: predictions(:)
        real(dp), intent(out) :: jacobian(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: full(:, :), num(:), den(:), e(:)
        real(dp) :: b(size(params))
        integer :: j
        if (stat%code /= STATUS_OK) return
        self%evaluations = self%evaluations + 1
        b = params
        allocate (full(size(self%x), size(params)))
        associate (x => self%x)
            select case (self%model)
            case (MODEL_EXP_RISE)
                if (any(-b(2)*x > log(huge(1.0_dp)))) then
                    call fail('exp(-b2 x) overflows')
                    return
                end if
                e = exp(-b(2)*x)
                predictions = b(1)*(1.0_dp - e)
                full(:, 1) = 1.0_dp - e
                full(:, 2) = b(1)*x*e
            case (MODEL_RATIONAL_12)
                num = x**2 + x*b(2)
                den = x**2 + x*b(3) + b(4)
                if (.not. all(abs(den) > TINY_DEN .and. abs(den) < HUGE_DEN)) then
                    call fail('the denominator vanishes or overflows')
                    return
                end if
                predictions = b(1)*num/den
                full(:, 1) = num/den
                full(:, 2) = b(1)*x/den
                full(:, 3) = -b(1)*num*x/den**2
                full(:, 4) = -b(1)*num/den**2
            case (MODEL_RATIONAL_33)
                num = b(1) + x*(b(2) + x*(b(3) + x*b(4)))
                den = 1.0_dp + x*(b(5) + x*(b(6) + x*b(7)))
                if (.not. all(abs(den) > TINY_DEN .and. abs(den) < HUGE_DEN)) then
                    call fail('the denominator vanishes or overflows')
                    return
                end if
                predictions = num/den
                do j = 1, 4
                    full(:, j) = x**(j - 1)/den
                end do
                do j = 5, 7
                    full(:, j) = -num*x**(j - 4)/den**2
                end do
            end select
        end associate
        ! far-off trial steps (BoxBOD from start 1) predict values whose
        ! squared residuals would overflow in the fit's cost sum, which the
        ! checking build traps: such a point is said not to be evaluable
        if (.not. all(abs(predictions) < HUGE_PRED)) then
            call fail('predictions beyond 1e100')
            return
        end if
        do j = 1, size(wrt)
            jacobian(:, j) = full(:, wrt(j))
        end do
    contains
        !> The model cannot be evaluated at these parameters (a trial step
        !! of the fit: it is damped), said as a status, not with an
        !! overflow (the checking build traps those).
        subroutine fail(why)
            character(len=*), intent(in) :: why
            predictions = 0.0_dp
            jacobian = 0.0_dp
            call set_status(stat, ERR_NUMERIC, 'nist model', why)
        end subroutine fail
    end subroutine nist_evaluate

    !> Misra1a, BoxBOD, MGH09 and Thurber, in that order.
    function nist_problems() result(p)
        type(nist_problem_t) :: p(4)

        p(1)%name = 'Misra1a'
        p(1)%model = MODEL_EXP_RISE
        p(1)%y = [10.07_dp, 14.73_dp, 17.94_dp, 23.93_dp, 29.61_dp, 35.18_dp, 40.02_dp, &
                  44.82_dp, 50.76_dp, 55.05_dp, 61.01_dp, 66.40_dp, 75.47_dp, 81.78_dp]
        p(1)%x = [77.6_dp, 114.9_dp, 141.1_dp, 190.8_dp, 239.9_dp, 289.0_dp, 332.8_dp, &
                  378.4_dp, 434.8_dp, 477.3_dp, 536.8_dp, 593.1_dp, 689.1_dp, 760.0_dp]
        p(1)%start1 = [500.0_dp, 1.0e-4_dp]
        p(1)%start2 = [250.0_dp, 5.0e-4_dp]
        p(1)%b = [2.3894212918e+02_dp, 5.5015643181e-04_dp]
        p(1)%sd = [2.7070075241e+00_dp, 7.2668688436e-06_dp]
        p(1)%rss = 1.2455138894e-01_dp

        p(2)%name = 'BoxBOD'
        p(2)%model = MODEL_EXP_RISE
        p(2)%y = [109.0_dp, 149.0_dp, 149.0_dp, 191.0_dp, 213.0_dp, 224.0_dp]
        p(2)%x = [1.0_dp, 2.0_dp, 3.0_dp, 5.0_dp, 7.0_dp, 10.0_dp]
        p(2)%start1 = [1.0_dp, 1.0_dp]
        p(2)%start2 = [100.0_dp, 0.75_dp]
        p(2)%b = [2.1380940889e+02_dp, 5.4723748542e-01_dp]
        p(2)%sd = [1.2354515176e+01_dp, 1.0455993237e-01_dp]
        p(2)%rss = 1.1680088766e+03_dp

        p(3)%name = 'MGH09'
        p(3)%model = MODEL_RATIONAL_12
        p(3)%y = [1.957e-01_dp, 1.947e-01_dp, 1.735e-01_dp, 1.600e-01_dp, 8.440e-02_dp, &
                  6.270e-02_dp, 4.560e-02_dp, 3.420e-02_dp, 3.230e-02_dp, 2.350e-02_dp, &
                  2.460e-02_dp]
        p(3)%x = [4.0_dp, 2.0_dp, 1.0_dp, 5.0e-01_dp, 2.5e-01_dp, 1.67e-01_dp, 1.25e-01_dp, &
                  1.0e-01_dp, 8.33e-02_dp, 7.14e-02_dp, 6.25e-02_dp]
        p(3)%start1 = [25.0_dp, 39.0_dp, 41.5_dp, 39.0_dp]
        p(3)%start2 = [0.25_dp, 0.39_dp, 0.415_dp, 0.39_dp]
        p(3)%b = [1.9280693458e-01_dp, 1.9128232873e-01_dp, 1.2305650693e-01_dp, &
                  1.3606233068e-01_dp]
        p(3)%sd = [1.1435312227e-02_dp, 1.9633220911e-01_dp, 8.0842031232e-02_dp, &
                   9.0025542308e-02_dp]
        p(3)%rss = 3.0750560385e-04_dp

        p(4)%name = 'Thurber'
        p(4)%model = MODEL_RATIONAL_33
        p(4)%y = [80.574_dp, 84.248_dp, 87.264_dp, 87.195_dp, 89.076_dp, 89.608_dp, &
                  89.868_dp, 90.101_dp, 92.405_dp, 95.854_dp, 100.696_dp, 101.060_dp, &
                  401.672_dp, 390.724_dp, 567.534_dp, 635.316_dp, 733.054_dp, 759.087_dp, &
                  894.206_dp, 990.785_dp, 1090.109_dp, 1080.914_dp, 1122.643_dp, 1178.351_dp, &
                  1260.531_dp, 1273.514_dp, 1288.339_dp, 1327.543_dp, 1353.863_dp, &
                  1414.509_dp, 1425.208_dp, 1421.384_dp, 1442.962_dp, 1464.350_dp, &
                  1468.705_dp, 1447.894_dp, 1457.628_dp]
        p(4)%x = [-3.067_dp, -2.981_dp, -2.921_dp, -2.912_dp, -2.840_dp, -2.797_dp, &
                  -2.702_dp, -2.699_dp, -2.633_dp, -2.481_dp, -2.363_dp, -2.322_dp, &
                  -1.501_dp, -1.460_dp, -1.274_dp, -1.212_dp, -1.100_dp, -1.046_dp, &
                  -0.915_dp, -0.714_dp, -0.566_dp, -0.545_dp, -0.400_dp, -0.309_dp, &
                  -0.109_dp, -0.103_dp, 0.010_dp, 0.119_dp, 0.377_dp, 0.790_dp, 0.963_dp, &
                  1.006_dp, 1.115_dp, 1.572_dp, 1.841_dp, 2.047_dp, 2.200_dp]
        p(4)%start1 = [1000.0_dp, 1000.0_dp, 400.0_dp, 40.0_dp, 0.7_dp, 0.3_dp, 0.03_dp]
        p(4)%start2 = [1300.0_dp, 1500.0_dp, 500.0_dp, 75.0_dp, 1.0_dp, 0.4_dp, 0.05_dp]
        p(4)%b = [1.2881396800e+03_dp, 1.4910792535e+03_dp, 5.8323836877e+02_dp, &
                  7.5416644291e+01_dp, 9.6629502864e-01_dp, 3.9797285797e-01_dp, &
                  4.9727297349e-02_dp]
        p(4)%sd = [4.6647963344e+00_dp, 3.9571156086e+01_dp, 2.8698696102e+01_dp, &
                   5.5675370270e+00_dp, 3.1333340687e-02_dp, 1.4984928198e-02_dp, &
                   6.5842344623e-03_dp]
        p(4)%rss = 5.6427082397e+03_dp
    end function nist_problems
end module nist_strd_data
