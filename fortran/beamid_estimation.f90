!> Generic weighted least-squares estimation and model diagnosis.
!!
!! Nothing here knows about beams: a concrete experiment type extends
!! `residual_model_t` and returns, for a full parameter vector, the predicted
!! value of every data row and the derivatives of those predictions with
!! respect to any requested parameters (`wrt`, 1-based indices into the
!! parameter vector). On top of that this module provides
!!
!! * `fit_least_squares`: weighted Gauss-Newton differential correction
!!   (Eq. 39, weights Eq. 53-54) with a Levenberg-Marquardt safeguard, box
!!   bounds and a priori pseudo-measurements (Eq. 142-145), and the covariance
!!   of Eq. 55 computed from the SVD of the column-scaled weighted Jacobian
!!   (rank-deficient directions get an infinite sigma, never a garbage inverse);
!! * `score_test`: the Lagrange-multiplier (score) test of a block of
!!   parameters held at their null values, with the free parameters projected
!!   out, one-sided for parameters whose null value is a bound;
!! * `diagnose`: score tests of every candidate block, likelihood-ratio refits
!!   of the leading ones, ranking, a verdict, rivals and the probe row that
!!   separates them best;
!! * `chi2_sf`: the chi-square survival function.
module beamid_estimation
    use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_positive_inf, ieee_quiet_nan, &
                                             ieee_is_finite, ieee_is_nan
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, clear_status, STATUS_OK, ERR_INPUT, &
                             ERR_NO_CONVERGENCE, ERR_NUMERIC, fmt_int, fmt_real
    use beamid_lapack, only: svd_thin
    implicit none
    private

    public :: residual_model_t, prior_t, fit_options_t, fit_result_t
    public :: score_result_t, candidate_t, diagnose_options_t, candidate_report_t
    public :: diagnosis_t, refit_info_t
    public :: fit_least_squares, fit_at, score_test, diagnose, chi2_sf, residual_structure
    public :: refit_effect, prior_from_covariance

    !> Per-parameter flags of a fit (worst first).
    integer, parameter, public :: FLAG_OK = 0           !< determined
    integer, parameter, public :: FLAG_UNDETERMINED = 1 !< infinite or > 100 % sigma
    integer, parameter, public :: FLAG_RUNAWAY = 2      !< moved by more than runaway_factor
    integer, parameter, public :: FLAG_CORRELATED = 3   !< |correlation| above corr_limit
    integer, parameter, public :: FLAG_AT_BOUND = 4     !< estimate sits on a bound
    !! priority when several apply: undetermined, runaway, at bound, correlated

    !> How a fit ended (fit_result_t%stop).
    integer, parameter, public :: STOP_CONVERGED = 0 !< a minimum to the tolerances
    integer, parameter, public :: STOP_STALLED = 1   !< no step lowers the cost any more,
    !! though the iterate is not a minimum (a bound, a solver limit, collinear columns)
    integer, parameter, public :: STOP_RUNAWAY = 2   !< a parameter ran away: held where
    !! it was found and the others fitted
    integer, parameter, public :: STOP_MAX_ITER = 3  !< still moving at the iteration limit
    integer, parameter, public :: STOP_EVALUATED = 4 !< evaluated at given values (fit_at)

    !> How rough a model answers (residual_model_t%rough, set by the fit while
    !! it iterates): accurate, the Jacobian rough (predictions at the user's
    !! tolerance), or predictions and Jacobian rough (the search's first
    !! phase). Each phase ends with the accurate evaluation at its final point.
    integer, parameter, public :: ROUGH_OFF = 0, ROUGH_JACOBIAN = 1, ROUGH_ALL = 2

    !> A damped crawl: CRAWL_STEPS damped steps lowering the chi-square by
    !! less than CRAWL_DROP together count as a stall (fit_least_squares).
    integer, parameter :: CRAWL_STEPS = 10
    real(dp), parameter :: CRAWL_DROP = 0.01_dp

    !> Starts of a refit with an effect switched on (refit_effect).
    integer, parameter, public :: START_NONE = 0        !< no start converged
    integer, parameter, public :: START_SCORE = 1       !< first-order (score) estimate
    integer, parameter, public :: START_NOMINAL = 2     !< the nominal model, effect at null
    integer, parameter, public :: START_CONTINUATION = 3 !< strength stepped from the null

    !> The words for the codes above, exported to Python (api_code_names):
    !! flags, how a fit ended, refit starts, candidate states.
    character(len=*), parameter, public :: FLAG_NAMES(0:4) = [character(len=43) :: 'ok', &
        'not determined by these data', 'ran away from its start', &
        'correlation near +-1 with another parameter', 'at a physical bound']
    character(len=*), parameter, public :: STOP_NAMES(0:4) = [character(len=15) :: &
        'converged', 'stalled', 'runaway', 'iteration limit', 'evaluated']
    character(len=*), parameter, public :: START_NAMES(0:3) = [character(len=20) :: &
        '', 'first-order estimate', 'nominal model', 'continuation']
    character(len=*), parameter, public :: CAND_NAMES(0:4) = [character(len=29) :: &
        'tested', 'already free', 'already switched on', 'not in this model', &
        'not seen by these experiments']

    !> Candidate states in a diagnosis.
    integer, parameter, public :: CAND_TESTED = 0   !< score test done
    integer, parameter, public :: CAND_FREE = 1     !< a parameter of it is already free
    integer, parameter, public :: CAND_ACTIVE = 2   !< a parameter is not at its null value
    integer, parameter, public :: CAND_NO_PARAMS = 3 !< the model has none of its parameters
    integer, parameter, public :: CAND_NOT_SEEN = 4  !< zero sensitivity on every data row

    !> An experiment family: predictions and sensitivities of its data rows.
    type, abstract :: residual_model_t
        !> Trial steps of the fit are judged on predictions alone, the
        !! sensitivities computed only at the step accepted (for a model whose
        !! predictions do not depend on whether sensitivities are asked, and
        !! whose sensitivities cost several plain evaluations: an integrated
        !! response)
        logical :: plain_trials = .false.
        !> The model can answer roughly (sensitivities, and on request
        !! predictions, integrated at a looser tolerance): set by models
        !! whose columns are integrated responses (beamid_inverse, for
        !! releases on the implicit integrator). Static models leave it off.
        logical :: rough_jacobian_ok = .false.
        !> Mode switch set by fit_least_squares while it iterates (only when
        !! rough_jacobian_ok; ROUGH_*): rough answers only steer the search;
        !! the estimates are confirmed, and the covariance computed, with the
        !! accurate model (rough = ROUGH_OFF) at the final point.
        integer :: rough = ROUGH_OFF
    contains
        procedure(evaluate_interface), deferred :: evaluate
    end type residual_model_t

    abstract interface
        !> Predictions of every data row at `params` (full vector) and their
        !! derivatives with respect to params(wrt(j)) in column j.
        subroutine evaluate_interface(self, params, wrt, predictions, jacobian, stat)
            import :: residual_model_t, dp, status_t
            class(residual_model_t), intent(inout) :: self
            real(dp), intent(in) :: params(:)
            integer, intent(in) :: wrt(:)
            real(dp), intent(out) :: predictions(:)
            real(dp), intent(out) :: jacobian(:, :)
            type(status_t), intent(inout) :: stat
        end subroutine evaluate_interface
    end interface

    !> A priori information (Eq. 142-145): parameter index, mean, sigma.
    !! Each entry adds the pseudo-measurement (mean - p) / sigma. With a full
    !! covariance E (a previous fit's, carried forward: Eq. 146-148, 164-166)
    !! `whiten` holds L^-1 for E = L L^T, and the pseudo-measurements are
    !! L^-1 (mean - p), whose weight is E^-1 (prior_from_covariance).
    type :: prior_t
        integer, allocatable :: index(:)
        real(dp), allocatable :: mean(:), sigma(:)
        real(dp), allocatable :: whiten(:, :)
    end type prior_t

    type :: fit_options_t
        integer :: max_iter = 50          !< Gauss-Newton iterations
        integer :: max_trials = 20        !< LM damping increases per iteration
        real(dp) :: tol_step = 1.0e-9_dp  !< converged when max |dp_i| / |p_i| is below
        real(dp) :: tol_cost = 1.0e-10_dp !< ... or the relative cost change is below
        !> ... or, after a damped or poorly predicted step, both the chi-square
        !! decrease it achieved and the one the next step predicts are below
        !! floor_chi2 (the cost's noise floor: every parameter within
        !! sqrt(floor_chi2) sigma of the linearized minimum)
        real(dp) :: floor_chi2 = 1.0e-2_dp
        real(dp) :: rcond = 1.0e-10_dp    !< rank cutoff on scaled singular values
        real(dp) :: corr_limit = 0.999_dp !< flag |correlation| above this
        real(dp) :: runaway_factor = 100.0_dp
    end type fit_options_t

    !> Result of a weighted least-squares fit.
    type :: fit_result_t
        real(dp), allocatable :: params(:)      !< full parameter vector at the estimates
        integer, allocatable :: free(:)         !< indices of the free parameters
        real(dp), allocatable :: estimates(:)   !< params(free)
        real(dp), allocatable :: sigmas(:)      !< sqrt(diag(cov)); +Inf if undetermined
        real(dp), allocatable :: cov(:, :)      !< Eq. 55 (pseudo-inverse if rank deficient)
        real(dp), allocatable :: corr(:, :)     !< correlations tau_ij of Eq. 55
        integer, allocatable :: flags(:)        !< FLAG_* per free parameter
        real(dp), allocatable :: predictions(:) !< model value of every data row
        real(dp), allocatable :: normalized(:)  !< (measured - model) / sigma
        real(dp) :: chi2 = 0.0_dp               !< sum of normalized^2 (data rows)
        real(dp) :: chi2_prior = 0.0_dp         !< a priori pseudo-measurement part
        real(dp) :: cond = 0.0_dp               !< condition number, column-scaled
        integer :: dof = 0                      !< rows + priors - free
        integer :: rank = 0
        integer :: iterations = 0
        logical :: converged = .false.
        integer :: stop = STOP_CONVERGED        !< STOP_*: how the iteration ended
        character(len=:), allocatable :: note   !< what happened, when not converged
        integer :: nlog = 0                     !< log entries (0 = start)
        real(dp), allocatable :: log_cost(:), log_lambda(:), log_step(:)
        real(dp), allocatable :: log_params(:, :) !< (nfree, 0:nlog)
    end type fit_result_t

    !> Score (Lagrange-multiplier) test of one block of parameters.
    type :: score_result_t
        integer, allocatable :: params(:)      !< parameter indices of the block
        real(dp), allocatable :: estimate(:)   !< first-order estimate (unconstrained)
        real(dp), allocatable :: sigma(:)      !< its sigma
        logical, allocatable :: active(:)      !< kept by the sign constraints
        real(dp), allocatable :: direction(:)  !< unit change of the weighted residuals
        real(dp), allocatable :: free_step(:)  !< first-order change of the free
        !! parameters that goes with the block's constrained estimate
        real(dp) :: drop = 0.0_dp              !< predicted chi-square drop (constrained)
        real(dp) :: p_value = 1.0_dp
        integer :: dof = 0
        logical :: physical = .true.           !< unconstrained estimate obeys the bounds
        logical :: identifiable = .true.       !< not in the span of the free columns
    end type score_result_t

    type :: candidate_t
        character(len=:), allocatable :: name
        integer, allocatable :: params(:)
    end type candidate_t

    type :: diagnose_options_t
        real(dp) :: alpha = 0.01_dp        !< family-wise significance (Bonferroni)
        integer :: nrefit = 3              !< leading candidates confirmed by refits
        real(dp) :: ambiguity_delta = 4.0_dp !< rivals: chi-square drops closer than this
        real(dp) :: collinear = 0.98_dp    !< ... or |cosine| of directions above this
        !> confirm by refits only candidates whose score test is significant at
        !! the family-wise level alpha (not yet divided by the number tested:
        !! a refit can gain more than the first-order test predicts when the
        !! effect's column is nearly in the span of the free ones, as J_elbow
        !! beside rho2; time histories make every refit costly)
        logical :: refit_significant_only = .false.
        !> stop a refit's starts at the first that converges with at least half
        !! the chi-square drop its score test predicts (the first-order start
        !! confirmed; the other starts are for fits far from the truth)
        logical :: first_enough = .false.
        !> the refit starts tried (refit_effect: first-order, nominal,
        !! continuation)
        logical :: starts(3) = .true.
    end type diagnose_options_t

    !> How a refit with an effect switched on went (refit_effect).
    type :: refit_info_t
        integer :: start = START_NONE       !< START_* of the refit kept
        integer :: tried = 0                !< starts tried
        character(len=:), allocatable :: note !< per start: what happened
    end type refit_info_t

    type :: candidate_report_t
        integer :: state = CAND_TESTED
        type(score_result_t) :: score
        logical :: refit_done = .false.
        logical :: refit_ok = .false.
        type(fit_result_t) :: refit
        type(refit_info_t) :: info          !< which start won, or why all failed
        real(dp) :: lr_drop = 0.0_dp      !< actual chi-square drop of the refit
        real(dp) :: lr_p = 1.0_dp
        logical :: significant = .false.
        logical :: acceptable = .false.   !< significant, physical, determined refit
        logical :: rival = .false.
        integer :: separating_row = 0     !< probe row separating it from the verdict
        real(dp) :: separation = 0.0_dp   !< |difference| / sigma at that row
    end type candidate_report_t

    type :: diagnosis_t
        type(candidate_report_t), allocatable :: cand(:)
        integer, allocatable :: ranking(:)  !< candidate indices, best first
        real(dp), allocatable :: cosine(:, :) !< between candidates' directions
        integer :: verdict = 0              !< 0: no candidate explains the residuals
        integer :: ntested = 0
        real(dp) :: alpha_each = 0.0_dp     !< per-candidate level after Bonferroni
    end type diagnosis_t

contains

    ! ----------------------------------------------------------------- helpers

    pure real(dp) function infinity()
        infinity = ieee_value(1.0_dp, ieee_positive_inf)
    end function infinity

    pure real(dp) function not_a_number()
        not_a_number = ieee_value(1.0_dp, ieee_quiet_nan)
    end function not_a_number

    !> Weighted system at `params`: rows (y - f)/sigma then a priori rows;
    !! a = d f / d params(cols) / sigma, prior rows 1/sigma_prior.
    subroutine weighted_system(model, y, sigma, params, cols, prior, pred, a, r, stat)
        class(residual_model_t), intent(inout) :: model
        real(dp), intent(in) :: y(:), sigma(:), params(:)
        integer, intent(in) :: cols(:)
        type(prior_t), intent(in) :: prior
        real(dp), intent(out) :: pred(:), a(:, :), r(:)
        type(status_t), intent(inout) :: stat
        integer :: m, i, j
        real(dp), allocatable :: jac(:, :)
        m = size(y)
        allocate (jac(m, size(cols)))
        call model%evaluate(params, cols, pred, jac, stat)
        if (stat%code /= STATUS_OK) return
        if (.not. (all(ieee_is_finite(pred)) .and. all(ieee_is_finite(jac)))) then
            call set_status(stat, ERR_NUMERIC, 'estimation', 'model returned non-finite '// &
                            'predictions or sensitivities')
            return
        end if
        do j = 1, size(cols)
            a(1:m, j) = jac(:, j)/sigma
        end do
        r(1:m) = (y - pred)/sigma
        a(m + 1:, :) = 0.0_dp
        if (allocated(prior%whiten)) then
            r(m + 1:) = matmul(prior%whiten, prior%mean - params(prior%index))
            do i = 1, size(prior%index)
                do j = 1, size(cols)
                    if (cols(j) == prior%index(i)) a(m + 1:, j) = prior%whiten(:, i)
                end do
            end do
            return
        end if
        do i = 1, size(prior%index)
            r(m + i) = (prior%mean(i) - params(prior%index(i)))/prior%sigma(i)
            do j = 1, size(cols)
                if (cols(j) == prior%index(i)) a(m + i, j) = 1.0_dp/prior%sigma(i)
            end do
        end do
    end subroutine weighted_system

    !> A priori information with a full covariance `cov` of the parameters
    !! `index` about `mean` (a previous fit carried forward, Eq. 146-148 and
    !! 164-166): whiten = L^-1 for the Cholesky factor cov = L L^T, sigma the
    !! square roots of the diagonal. A covariance that is not symmetric
    !! positive definite (an undetermined direction) is bad input.
    pure subroutine prior_from_covariance(index, mean, cov, prior, stat)
        integer, intent(in) :: index(:)
        real(dp), intent(in) :: mean(:), cov(:, :)
        type(prior_t), intent(out) :: prior
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: l(:, :), w(:, :)
        integer :: n, i, j, k
        n = size(index)
        if (size(mean) /= n .or. size(cov, 1) /= n .or. size(cov, 2) /= n) then
            call set_status(stat, ERR_INPUT, 'a priori covariance', 'sizes differ: '// &
                            fmt_int(n)//' parameters')
            return
        end if
        if (.not. all(ieee_is_finite(cov))) then
            call set_status(stat, ERR_INPUT, 'a priori covariance', 'not finite (a '// &
                            'parameter the previous data did not determine)')
            return
        end if
        allocate (l(n, n), w(n, n))
        l = 0.0_dp
        do j = 1, n
            l(j, j) = cov(j, j) - sum(l(j, 1:j - 1)**2)
            if (.not. l(j, j) > 0.0_dp) then
                call set_status(stat, ERR_INPUT, 'a priori covariance', 'not positive '// &
                                'definite at parameter '//fmt_int(index(j)))
                return
            end if
            l(j, j) = sqrt(l(j, j))
            do i = j + 1, n
                l(i, j) = (0.5_dp*(cov(i, j) + cov(j, i)) - &
                           sum(l(i, 1:j - 1)*l(j, 1:j - 1)))/l(j, j)
            end do
        end do
        ! w = L^-1 (lower triangular, forward substitution per column)
        w = 0.0_dp
        do k = 1, n
            w(k, k) = 1.0_dp/l(k, k)
            do i = k + 1, n
                w(i, k) = -sum(l(i, k:i - 1)*w(k:i - 1, k))/l(i, i)
            end do
        end do
        prior%index = index
        prior%mean = mean
        prior%sigma = [(sqrt(cov(i, i)), i=1, n)]
        prior%whiten = w
    end subroutine prior_from_covariance

    !> Thin SVD of a with columns scaled to unit norm: a = u s vt d.
    subroutine scaled_svd(a, d, s, u, vt, stat)
        real(dp), intent(in) :: a(:, :)
        real(dp), intent(out) :: d(:), s(:), u(:, :), vt(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: work(:, :)
        integer :: j
        allocate (work, source=a)
        do j = 1, size(a, 2)
            d(j) = norm2(a(:, j))
            if (d(j) <= tiny(1.0_dp)) d(j) = 1.0_dp
            work(:, j) = work(:, j)/d(j)
        end do
        call svd_thin(work, s, u, vt, stat)
    end subroutine scaled_svd

    !> Damped least-squares step min |r - a dx|^2 + lambda |d dx|^2 from the
    !! scaled SVD (Levenberg-Marquardt with Marquardt's column scaling).
    pure function lm_step(d, s, u, vt, r, lambda, rcond) result(dx)
        real(dp), intent(in) :: d(:), s(:), u(:, :), vt(:, :), r(:), lambda, rcond
        real(dp) :: dx(size(d))
        real(dp) :: z(size(d)), c
        integer :: k
        z = 0.0_dp
        do k = 1, size(s)
            if (s(k) <= rcond*s(1)) cycle
            c = dot_product(u(:, k), r)*s(k)/(s(k)**2 + lambda)
            z = z + c*vt(k, :)
        end do
        dx = z/d
    end function lm_step

    !> Cost decrease predicted for the undamped (Gauss-Newton) step.
    pure real(dp) function predicted_decrease(s, u, r, rcond)
        real(dp), intent(in) :: s(:), u(:, :), r(:), rcond
        integer :: k
        predicted_decrease = 0.0_dp
        do k = 1, size(s)
            if (s(k) > rcond*s(1)) predicted_decrease = predicted_decrease + &
                dot_product(u(:, k), r)**2
        end do
    end function predicted_decrease

    !> Covariance (Eq. 55) from the weighted Jacobian a (rows x n).
    subroutine covariance(a, opts, cov, sig, corr, cond, rank, undetermined, stat)
        real(dp), intent(in) :: a(:, :)
        type(fit_options_t), intent(in) :: opts
        real(dp), intent(out) :: cov(:, :), sig(:), corr(:, :), cond
        integer, intent(out) :: rank
        logical, intent(out) :: undetermined(:)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: d(:), s(:), u(:, :), vt(:, :)
        integer :: n, r, k, i, j
        n = size(a, 2)
        r = min(size(a, 1), n)
        cov = 0.0_dp
        corr = 0.0_dp
        sig = infinity()
        undetermined = .true.
        cond = infinity()
        rank = 0
        if (n == 0) then
            cond = 1.0_dp
            return
        end if
        if (r == 0) return
        allocate (d(n), s(r), u(size(a, 1), r), vt(r, n))
        call scaled_svd(a, d, s, u, vt, stat)
        if (stat%code /= STATUS_OK) return
        rank = count(s > opts%rcond*s(1))
        if (s(1) <= 0.0_dp) rank = 0
        if (r == n) then   ! nested: s has no n-th entry when r < n
            if (s(n) > 0.0_dp) cond = s(1)/s(n)
        end if
        do k = 1, rank
            do j = 1, n
                cov(:, j) = cov(:, j) + vt(k, :)*vt(k, j)/s(k)**2
            end do
        end do
        do j = 1, n
            cov(:, j) = cov(:, j)/d/d(j)
        end do
        ! a parameter with a component in the null space is undetermined
        undetermined = .false.
        if (rank < n) then
            do i = 1, n
                ! squared norm of row i of V over the kept directions
                if (1.0_dp - sum(vt(1:rank, i)**2) > 1.0e-6_dp) undetermined(i) = .true.
            end do
        end if
        do i = 1, n
            if (.not. undetermined(i)) sig(i) = sqrt(max(cov(i, i), 0.0_dp))
        end do
        do j = 1, n
            do i = 1, n
                if (undetermined(i) .or. undetermined(j)) then
                    corr(i, j) = not_a_number()
                else if (sig(i) > 0.0_dp .and. sig(j) > 0.0_dp) then
                    corr(i, j) = cov(i, j)/(sig(i)*sig(j))
                else
                    corr(i, j) = merge(1.0_dp, 0.0_dp, i == j)
                end if
            end do
        end do
    end subroutine covariance

    ! ------------------------------------------------------------ validation

    subroutine check_problem(y, sigma, params, free, lower, upper, prior, stat)
        real(dp), intent(in) :: y(:), sigma(:), params(:), lower(:), upper(:)
        integer, intent(in) :: free(:)
        type(prior_t), intent(in) :: prior
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'fit'
        integer :: i, np
        np = size(params)
        if (size(sigma) /= size(y)) then
            call set_status(stat, ERR_INPUT, where, 'sigma has '//fmt_int(size(sigma))// &
                            ' values for '//fmt_int(size(y))//' data rows')
            return
        end if
        if (size(y) == 0) then
            call set_status(stat, ERR_INPUT, where, 'no data rows')
            return
        end if
        do i = 1, size(y)
            if (.not. ieee_is_finite(y(i))) then
                call set_status(stat, ERR_INPUT, where, 'data row '//fmt_int(i)// &
                                ' value = '//fmt_real(y(i))//', expected a finite number')
                return
            end if
            if (.not. (sigma(i) > 0.0_dp .and. ieee_is_finite(sigma(i)))) then
                call set_status(stat, ERR_INPUT, where, 'data row '//fmt_int(i)// &
                                ' sigma = '//fmt_real(sigma(i))//', expected sigma > 0')
                return
            end if
        end do
        if (size(lower) /= np .or. size(upper) /= np) then
            call set_status(stat, ERR_INPUT, where, 'bounds do not match the parameter vector')
            return
        end if
        if (size(free) == 0) then
            call set_status(stat, ERR_INPUT, where, 'no free parameters: name at least one')
            return
        end if
        do i = 1, size(free)
            if (free(i) < 1 .or. free(i) > np) then
                call set_status(stat, ERR_INPUT, where, 'free parameter index '// &
                                fmt_int(free(i))//' outside 1..'//fmt_int(np))
                return
            end if
            if (count(free == free(i)) > 1) then
                call set_status(stat, ERR_INPUT, where, 'free parameter index '// &
                                fmt_int(free(i))//' given twice')
                return
            end if
            if (params(free(i)) < lower(free(i)) .or. params(free(i)) > upper(free(i))) then
                call set_status(stat, ERR_INPUT, where, 'starting value of parameter '// &
                                fmt_int(free(i))//' = '//fmt_real(params(free(i)))// &
                                ' is outside its bounds ['//fmt_real(lower(free(i)))//', '// &
                                fmt_real(upper(free(i)))//']')
                return
            end if
        end do
        if (size(prior%mean) /= size(prior%index) .or. &
            size(prior%sigma) /= size(prior%index)) then
            call set_status(stat, ERR_INPUT, where, 'prior index, mean and sigma differ in size')
            return
        end if
        do i = 1, size(prior%index)
            if (.not. any(free == prior%index(i))) then
                call set_status(stat, ERR_INPUT, where, 'a priori parameter '// &
                                fmt_int(prior%index(i))//' is not free')
                return
            end if
            if (.not. (prior%sigma(i) > 0.0_dp .and. ieee_is_finite(prior%sigma(i)))) then
                call set_status(stat, ERR_INPUT, where, 'a priori sigma of parameter '// &
                                fmt_int(prior%index(i))//' = '//fmt_real(prior%sigma(i))// &
                                ', expected sigma > 0')
                return
            end if
            if (.not. ieee_is_finite(prior%mean(i))) then
                call set_status(stat, ERR_INPUT, where, 'a priori mean of parameter '// &
                                fmt_int(prior%index(i))//' is not finite')
                return
            end if
        end do
    end subroutine check_problem

    ! ----------------------------------------------------------------- fitting

    !> Weighted Gauss-Newton differential correction (Eq. 39, 54) of the
    !! parameters params(free), starting from params0, with a priori
    !! pseudo-measurements (Eq. 142-145) and bounds lower <= p <= upper (a step
    !! that would leave the box is clipped to it). A step that does not reduce
    !! the cost is retried with Levenberg-Marquardt damping. Converged (in
    !! statistical units, docs/workflow.md "When a fit has converged") when
    !! * the Gauss-Newton step would lower the chi-square by less than
    !!   tol_cost times the cost, or an undamped step moved the parameters by
    !!   less than tol_step relatively or the cost by less than tol_cost
    !!   relatively (a smooth model: quadratic convergence to working
    !!   precision, the dissertation's iteration counts on exact data);
    !! * at the cost's noise floor: a damped (or poorly predicted) step lowered
    !!   the chi-square by less than floor_chi2 (0.01) and the next Gauss-Newton
    !!   step predicts less than floor_chi2 more (every parameter within 0.1
    !!   sigma of the linearized minimum; an integrated response is not smooth
    !!   in the parameters below that).
    !!
    !! How the iteration ended is `res%stop` (STOP_*), said in words in
    !! `res%note`; every ending but one comes back with STATUS_OK and the
    !! parameters flagged:
    !! * a parameter that runs away (beyond runaway_factor times its start, or
    !!   for a parameter bounded below by 0, below its start over that factor
    !!   squared) is held where it was found and the others are fitted on
    !!   (STOP_RUNAWAY; the held one gets an infinite sigma and
    !!   FLAG_UNDETERMINED);
    !! * three damped steps in a row that change neither the parameters nor the
    !!   cost while the damping had to be raised again, ten damped steps that
    !!   lower the chi-square by less than 0.01 together (a crawl along a
    !!   curved valley), or damped trial steps the model cannot solve down to
    !!   the smallest, is a stall (STOP_STALLED): the note names the parameters
    !!   at a bound, running away or collinear, and the solver's message;
    !! * still moving at max_iter: ERR_NO_CONVERGENCE (STOP_MAX_ITER), `res`
    !!   holding the last iterate and its log;
    !! * a model that cannot be evaluated at params0 (the values asked): the
    !!   model's own status (genuine numerical failure).
    !!
    !! Rough phases (a model with rough_jacobian_ok: an integrated response
    !! whose runs cost more the tighter their tolerance, and whose
    !! sensitivities cost several runs): the search only needs to get near
    !! the minimum, so it starts on the rough model (model%rough = ROUGH_ALL:
    !! predictions and sensitivities at a looser integration tolerance, runs
    !! a twentieth of the user's), then, if needed, goes on with rough
    !! Jacobians and residuals at the user's tolerance (ROUGH_JACOBIAN), then
    !! with the accurate model. Each phase ends (converged, noise floor or
    !! stall) with the accurate predictions and Jacobian at its final point
    !! and the Gauss-Newton decrease they predict; the fit goes on to the
    !! next phase only while that still promises more than floor_chi2, so
    !! the estimates are the minimum of the accurate model to the same
    !! criterion. The covariance, sigmas, flags and condition number always
    !! come from the accurate Jacobian. Static models never use rough mode.
    subroutine fit_least_squares(model, y, sigma, params0, free, lower, upper, prior, opts, &
                                 res, stat)
        class(residual_model_t), intent(inout) :: model
        real(dp), intent(in) :: y(:), sigma(:), params0(:), lower(:), upper(:)
        integer, intent(in) :: free(:)
        type(prior_t), intent(in) :: prior
        type(fit_options_t), intent(in) :: opts
        type(fit_result_t), intent(out) :: res
        type(status_t), intent(inout) :: stat
        integer :: m, n, mt, r, it, it0, trial, i, nstuck, nbound
        logical :: go_on
        real(dp), allocatable :: p(:), pt(:), pred(:), predt(:), a(:, :), at(:, :), rr(:), rt(:)
        real(dp), allocatable :: aa(:, :), g(:)
        real(dp), allocatable :: d(:), s(:), u(:, :), vt(:, :), dx(:)
        real(dp) :: cost, cost_t, lambda, relstep, dcost, lam_floor, lambda_in
        real(dp) :: pred_gn, pred_step
        logical :: accepted, evaluated, failed_trial, stalled, stall_pending, poor_step
        integer :: level
        type(status_t) :: trial_stat, fail_stat
        logical, allocatable :: undetermined(:), held(:)

        call check_problem(y, sigma, params0, free, lower, upper, prior, stat)
        if (stat%code /= STATUS_OK) return
        m = size(y)
        n = size(free)
        mt = m + size(prior%index)
        r = min(mt, n)
        allocate (pred(m), predt(m), a(mt, n), at(mt, n), rr(mt), rt(mt))
        allocate (d(n), s(r), u(mt, r), vt(r, n), dx(n), held(n))
        allocate (res%log_cost(0:opts%max_iter), res%log_lambda(0:opts%max_iter), &
                  res%log_step(0:opts%max_iter), res%log_params(n, 0:opts%max_iter))
        res%free = free
        p = params0
        ! the search starts on the rough model when the model has one
        ! (confirm_at_final_point makes each phase's end point accurate)
        model%rough = ROUGH_OFF
        if (model%rough_jacobian_ok) model%rough = ROUGH_ALL
        call weighted_system(model, y, sigma, p, free, prior, pred, a, rr, stat)
        if (stat%code /= STATUS_OK .and. model%rough == ROUGH_ALL) then
            ! not solvable at the rough tolerance: start at the user's
            call clear_status(stat)
            model%rough = ROUGH_JACOBIAN
            call weighted_system(model, y, sigma, p, free, prior, pred, a, rr, stat)
        end if
        if (stat%code /= STATUS_OK) then
            model%rough = ROUGH_OFF
            stat%message = trim(stat%message)//' (at the starting values)'
            return
        end if
        cost = sum(rr**2)
        res%nlog = 0
        res%log_cost(0) = cost
        res%log_lambda(0) = 0.0_dp
        res%log_step(0) = 0.0_dp
        res%log_params(:, 0) = p(free)
        lambda = 0.0_dp
        res%converged = .false.
        res%stop = STOP_MAX_ITER
        relstep = 0.0_dp
        dcost = 0.0_dp
        held = .false.
        nstuck = 0
        stalled = .false.
        stall_pending = .false.
        poor_step = .false.
        pred_step = 0.0_dp
        failed_trial = .false.
        it0 = 1
        ! phases: iterate (on the rough model, then steered by rough
        ! Jacobians, when the model offers them), confirm at the final point
        ! with the accurate model and iterate on, one level less rough, while
        ! it promises more than the noise floor (the inner loop's body is the
        ! one Gauss-Newton step)
        phases: do
        iterate: do it = it0, opts%max_iter
            call projected_svd(stat)
            if (stat%code /= STATUS_OK) then
                model%rough = ROUGH_OFF
                return
            end if
            lam_floor = 1.0e-6_dp*s(1)**2
            ! first-order optimality: the undamped step would lower the cost by
            ! pred_gn = |U^T r|^2 = dx^T (A^T A) dx, the squared length of the
            ! step in units of the parameters' covariance (Eq. 55), so that
            ! |dx_i| <= sqrt(pred_gn) sigma_i for every parameter. Converged when
            ! that is negligible against the cost, or the data are matched to
            ! 1e-9 sigma a row (exact synthetic data)
            pred_gn = predicted_decrease(s, u, rr, opts%rcond)
            if (pred_gn <= opts%tol_cost*cost + tiny(1.0_dp) .or. cost <= 1.0e-18_dp*mt) then
                res%converged = .true.
                res%iterations = it - 1
                exit
            end if
            ! the cost's noise floor: the last step had to be damped or gained
            ! less than a quarter of its linear prediction (the model is not
            ! smooth at this scale: an integrated response's switching events,
            ! its error control), it lowered the chi-square by less than
            ! floor_chi2 and the next step promises less than floor_chi2 more:
            ! what is left to gain has no statistical meaning
            if (it > 1 .and. poor_step .and. dcost <= opts%floor_chi2 .and. &
                pred_gn <= opts%floor_chi2) then
                res%converged = .true.
                res%iterations = it - 1
                exit
            end if
            ! the rough model pays while the misfit is well above the data's
            ! noise; once the data are fitted better than their sigmas (chi2
            ! below half the degrees of freedom, as with exact data) what is
            ! left may be the rough model's own error: on to the accurate one
            if (model%rough == ROUGH_ALL .and. cost < 0.5_dp*max(mt - n, 1)) then
                res%converged = .true.
                res%iterations = it - 1
                exit
            end if
            if (stall_pending) then
                res%iterations = it - 1
                stalled = .true.
                exit
            end if
            accepted = .false.
            evaluated = .false.
            failed_trial = .false.
            lambda_in = lambda
            do trial = 1, opts%max_trials
                dx = lm_step(d, s, u, vt, rr, lambda, opts%rcond)
                pt = p
                pt(free) = min(max(p(free) + dx, lower(free)), upper(free))
                dx = pt(free) - p(free)
                call clear_status(trial_stat)
                if (model%plain_trials) then
                    call weighted_system(model, y, sigma, pt, free(1:0), prior, predt, at(:, 1:0), &
                                         rt, trial_stat)
                else
                    call weighted_system(model, y, sigma, pt, free, prior, predt, at, rt, trial_stat)
                end if
                if (trial_stat%code == STATUS_OK) then
                    evaluated = .true.
                    failed_trial = .false.
                    cost_t = sum(rt**2)
                    if (cost_t <= cost*(1.0_dp + 8.0_dp*epsilon(1.0_dp)) + tiny(1.0_dp)) then
                        ! the sensitivities at the accepted step
                        if (model%plain_trials) call weighted_system(model, y, sigma, pt, free, &
                                                 prior, predt, at, rt, trial_stat)
                        if (trial_stat%code == STATUS_OK) then
                            cost_t = sum(rt**2)
                            accepted = .true.
                            exit
                        end if
                        failed_trial = .true.
                        fail_stat = trial_stat
                    end if
                else
                    failed_trial = .true.
                    fail_stat = trial_stat
                end if
                lambda = max(10.0_dp*lambda, 1.0e-3_dp*s(1)**2)
            end do
            res%iterations = it
            if (.not. accepted) then
                ! no damped step lowers the cost: a minimum to working precision
                ! when the smallest trial step could be evaluated; a stall when
                ! it could not (the model could not be solved at the fit's own
                ! trial parameters, however short the step: the fit comes back at
                ! its last good point, flagged, with the solver's message)
                if (failed_trial .or. .not. evaluated) then
                    stalled = .true.
                else
                    res%converged = .true.
                end if
                exit
            end if
            relstep = maxval(abs(dx)/max(abs(p(free)), abs(pt(free)), tiny(1.0_dp)))
            dcost = cost - cost_t
            pred_step = cost - sum((rr - matmul(aa, dx))**2)
            poor_step = lambda > 0.0_dp .or. dcost < 0.25_dp*pred_step
            p = pt
            pred = predt
            a = at
            rr = rt
            res%nlog = it
            res%log_cost(it) = cost_t
            res%log_lambda(it) = lambda
            res%log_step(it) = relstep
            res%log_params(:, it) = p(free)
            if (lambda == 0.0_dp .and. (relstep < opts%tol_step .or. &
                dcost <= opts%tol_cost*cost_t .or. cost_t <= 1.0e-18_dp*mt)) then
                cost = cost_t
                res%converged = .true.
                exit
            end if
            ! a damped step that moves nothing though the damping had to be
            ! raised again (not on its way down): three in a row is a stall
            if (lambda > lambda_in .and. &
                (relstep < opts%tol_step .or. dcost <= opts%tol_cost*cost_t)) then
                nstuck = nstuck + 1
            else
                nstuck = 0
            end if
            cost = cost_t
            ! ... and so is a damped crawl: ten damped steps that lower the
            ! chi-square by less than 0.01 together (a curved valley along
            ! collinear columns; no statistical meaning is left to gain)
            if (it > CRAWL_STEPS) then
                if (all(res%log_lambda(it - CRAWL_STEPS + 1:it) > 0.0_dp) .and. &
                    res%log_cost(it - CRAWL_STEPS) - cost_t < CRAWL_DROP) nstuck = 3
            end if
            if (nstuck >= 3) then
                ! a stall unless the next iterate's test finds the noise floor
                if (it == opts%max_iter) then
                    stalled = .true.
                    exit
                end if
                stall_pending = .true.
            end if
            lambda = lambda/10.0_dp
            if (lambda < lam_floor) lambda = 0.0_dp
            ! a parameter that ran away is held there; the others go on
            do i = 1, n
                if (held(i)) cycle
                if (ran_away(p(free(i)), params0(free(i)), lower(free(i)), opts)) then
                    held(i) = .true.
                    lambda = 0.0_dp
                    nstuck = 0
                    stall_pending = .false.
                end if
            end do
            if (all(held)) exit
        end do iterate
        if (model%rough == ROUGH_OFF) exit phases
        level = model%rough
        call confirm_at_final_point(go_on, stat)
        if (stat%code /= STATUS_OK) return
        if (.not. go_on) exit phases
        model%rough = level - 1
        call restart_phase()
        end do phases
        res%log_cost = res%log_cost(0:res%nlog)
        res%log_lambda = res%log_lambda(0:res%nlog)
        res%log_step = res%log_step(0:res%nlog)
        res%log_params = res%log_params(:, 0:res%nlog)

        res%params = p
        res%estimates = p(free)
        res%predictions = pred
        res%normalized = rr(1:m)
        res%chi2 = sum(rr(1:m)**2)
        res%chi2_prior = sum(rr(m + 1:)**2)
        res%dof = mt - n
        allocate (res%cov(n, n), res%corr(n, n), res%sigmas(n), res%flags(n), undetermined(n))
        ! a held parameter's column is left out: the others' covariance is
        ! conditional on it, and it gets an infinite sigma
        aa = a
        do i = 1, n
            if (held(i)) aa(:, i) = 0.0_dp
        end do
        call clear_status(trial_stat)
        call covariance(aa, opts, res%cov, res%sigmas, res%corr, res%cond, res%rank, &
                        undetermined, trial_stat)
        if (trial_stat%code /= STATUS_OK) then
            if (stat%code == STATUS_OK) stat = trial_stat
            return
        end if
        call set_flags(res, params0, lower, upper, undetermined, opts)
        if (stat%code /= STATUS_OK) return   ! the model failed at every trial step
        if (any(held)) then
            res%stop = STOP_RUNAWAY
            if (all(held)) then
                res%note = 'no parameter left to fit'
            else if (res%converged) then
                res%note = 'the others fitted'
            else if (stalled) then
                res%note = 'the others stalled'
            else
                res%note = 'the others still moving at the iteration limit'
            end if
            res%note = flag_list(res, params0, lower, upper, opts, held)// &
                       '; held where found after '//fmt_int(res%iterations)// &
                       ' iterations, '//res%note
            res%converged = .false.
        else if (stalled) then
            res%converged = .false.
            res%stop = STOP_STALLED
            res%note = 'Gauss-Newton stalled after '//fmt_int(res%iterations)// &
                       ' iterations (last relative step '//fmt_real(relstep)// &
                       ', cost change '//fmt_real(dcost)//', damping '//fmt_real(lambda)//'): '
            if (failed_trial) then
                res%note = res%note//'the model could not be solved at the smallest trial '// &
                           'step ('//trim(fail_stat%message)//'); '
            end if
            res%note = res%note//flag_list(res, params0, lower, upper, opts, held)
        else if (res%converged) then
            res%stop = STOP_CONVERGED
        else
            res%stop = STOP_MAX_ITER
            call set_status(stat, ERR_NO_CONVERGENCE, 'fit', 'Gauss-Newton did not converge '// &
                            'in '//fmt_int(res%iterations)//' iterations (last relative step '// &
                            fmt_real(relstep)//', cost change '//fmt_real(dcost)// &
                            ', chi-square '//fmt_real(res%chi2)//')')
            res%note = trim(stat%message)
        end if

    contains

        !> Projected Gauss-Newton: a parameter on a bound whose descent
        !! direction (a^T r) points out of the box is held for this step, a
        !! parameter that ran away for good; aa = a without their columns and
        !! its scaled SVD (d, s, u, vt).
        subroutine projected_svd(st)
            type(status_t), intent(inout) :: st
            aa = a
            g = matmul(rr, a)
            do i = 1, n
                if (held(i) .or. (p(free(i)) <= lower(free(i)) .and. g(i) < 0.0_dp) .or. &
                    (p(free(i)) >= upper(free(i)) .and. g(i) > 0.0_dp)) aa(:, i) = 0.0_dp
            end do
            call scaled_svd(aa, d, s, u, vt, st)
            if (st%code /= STATUS_OK) return
            ! ... and one on a bound that the Gauss-Newton step would push out
            ! of the box (a clipped step would crawl along the bound)
            do trial = 1, n
                dx = lm_step(d, s, u, vt, rr, 0.0_dp, opts%rcond)
                nbound = 0
                do i = 1, n
                    if (all(aa(:, i) == 0.0_dp)) cycle
                    if ((p(free(i)) <= lower(free(i)) .and. dx(i) < 0.0_dp) .or. &
                        (p(free(i)) >= upper(free(i)) .and. dx(i) > 0.0_dp)) then
                        aa(:, i) = 0.0_dp
                        nbound = nbound + 1
                    end if
                end do
                if (nbound == 0) exit
                call scaled_svd(aa, d, s, u, vt, st)
                if (st%code /= STATUS_OK) return
            end do
        end subroutine projected_svd

        !> The end of a rough phase: predictions and Jacobian at the user's
        !! tolerance at the final point (one sensitivity run), and the
        !! Gauss-Newton decrease they predict. go_on: that still promises more
        !! than the noise floor and iterations are left. After the phase on
        !! the rough model the floor is scaled by the misfit, chi-square per
        !! degree of freedom (about 1 with noisy data: the same floor): with
        !! (nearly) exact data the rough model's own noise floor is far above
        !! the accurate model's, and the fit goes on to the accurate minimum.
        subroutine confirm_at_final_point(go_on, st)
            logical, intent(out) :: go_on
            type(status_t), intent(inout) :: st
            type(status_t) :: est
            model%rough = ROUGH_OFF
            go_on = .false.
            call weighted_system(model, y, sigma, p, free, prior, pred, a, rr, est)
            if (est%code /= STATUS_OK) then
                est%message = trim(est%message)//' (the accurate Jacobian at the estimates)'
                st = est
                return
            end if
            cost = sum(rr**2)
            if (all(held) .or. res%iterations >= opts%max_iter) return
            call projected_svd(est)
            if (est%code /= STATUS_OK) then
                st = est
                return
            end if
            pred_gn = predicted_decrease(s, u, rr, opts%rcond)
            if (level == ROUGH_ALL) then
                go_on = pred_gn > opts%floor_chi2*min(1.0_dp, cost/max(mt - n, 1)) .and. &
                        cost > 1.0e-18_dp*mt
            else
                go_on = pred_gn > opts%floor_chi2
            end if
        end subroutine confirm_at_final_point

        !> Iterate on from the final point (one level less rough), the
        !! iteration's state as after an undamped step.
        subroutine restart_phase()
            it0 = res%iterations + 1
            res%converged = .false.
            stalled = .false.
            stall_pending = .false.
            failed_trial = .false.
            poor_step = .false.
            nstuck = 0
            lambda = 0.0_dp
        end subroutine restart_phase
    end subroutine fit_least_squares

    !> Has x run away from its start x0: beyond runaway_factor times |x0|, or
    !! for a parameter bounded below by 0 (a stiffness: the solver never
    !! reaches 0) below x0 / runaway_factor**2? (Shrinking is judged more
    !! leniently: from an absurd start, 3000 -> 7, a stiffness may legitimately
    !! fall by a factor of 100 on its way back.)
    pure logical function ran_away(x, x0, lo, opts)
        real(dp), intent(in) :: x, x0, lo
        type(fit_options_t), intent(in) :: opts
        ran_away = .false.
        if (x0 == 0.0_dp) return
        if (abs(x) > opts%runaway_factor*abs(x0)) ran_away = .true.
        if (lo == 0.0_dp .and. x0 > 0.0_dp .and. x < x0/opts%runaway_factor**2) &
            ran_away = .true.
    end function ran_away

    !> The flagged parameters of a fit in words ("parameter k" by index):
    !! running away, at a bound, collinear, not determined.
    function flag_list(res, params0, lower, upper, opts, held) result(text)
        type(fit_result_t), intent(in) :: res
        real(dp), intent(in) :: params0(:), lower(:), upper(:)
        type(fit_options_t), intent(in) :: opts
        logical, intent(in) :: held(:)
        character(len=:), allocatable :: text
        integer :: i, j, k, n
        real(dp) :: x
        n = size(res%free)
        text = ''
        do i = 1, n
            k = res%free(i)
            x = res%estimates(i)
            if (held(i) .or. ran_away(x, params0(k), lower(k), opts)) then
                call add('parameter '//fmt_int(k)//' ran away ('//fmt_real(params0(k))// &
                         ' -> '//fmt_real(x)//')')
            else if (x <= lower(k) .or. x >= upper(k)) then
                call add('parameter '//fmt_int(k)//' at its bound '//fmt_real(x))
            else if (res%flags(i) == FLAG_UNDETERMINED) then
                call add('parameter '//fmt_int(k)//' not determined')
            end if
        end do
        do i = 1, n
            do j = i + 1, n
                if (ieee_is_nan(res%corr(i, j))) cycle
                if (abs(res%corr(i, j)) > opts%corr_limit) &
                    call add('parameters '//fmt_int(res%free(i))//' and '// &
                             fmt_int(res%free(j))//' collinear (correlation '// &
                             fmt_real(res%corr(i, j))//')')
            end do
        end do
        if (len(text) == 0) text = 'no parameter at a bound, running away or collinear: '// &
            'no damped step along the sensitivities lowers the cost (the model is not '// &
            'smooth to working precision there)'
    contains
        subroutine add(item)
            character(len=*), intent(in) :: item
            if (len(text) > 0) text = text//', '
            text = text//item
        end subroutine add
    end function flag_list

    !> The fit result at given parameter values (estimates found earlier),
    !! without iterating: residuals, chi-square, covariance and flags
    !! (res%stop = STOP_EVALUATED, res%converged = .true.).
    subroutine fit_at(model, y, sigma, params, free, lower, upper, prior, opts, res, stat)
        class(residual_model_t), intent(inout) :: model
        real(dp), intent(in) :: y(:), sigma(:), params(:), lower(:), upper(:)
        integer, intent(in) :: free(:)
        type(prior_t), intent(in) :: prior
        type(fit_options_t), intent(in) :: opts
        type(fit_result_t), intent(out) :: res
        type(status_t), intent(inout) :: stat
        integer :: m, n, mt
        real(dp), allocatable :: pred(:), a(:, :), rr(:)
        logical, allocatable :: undetermined(:)
        call check_problem(y, sigma, params, free, lower, upper, prior, stat)
        if (stat%code /= STATUS_OK) return
        m = size(y)
        n = size(free)
        mt = m + size(prior%index)
        allocate (pred(m), a(mt, n), rr(mt))
        call weighted_system(model, y, sigma, params, free, prior, pred, a, rr, stat)
        if (stat%code /= STATUS_OK) return
        res%free = free
        res%params = params
        res%estimates = params(free)
        res%predictions = pred
        res%normalized = rr(1:m)
        res%chi2 = sum(rr(1:m)**2)
        res%chi2_prior = sum(rr(m + 1:)**2)
        res%dof = mt - n
        res%converged = .true.
        res%stop = STOP_EVALUATED
        res%nlog = 0
        res%log_cost = [sum(rr**2)]
        res%log_lambda = [0.0_dp]
        res%log_step = [0.0_dp]
        res%log_params = reshape(params(free), [n, 1])
        allocate (res%cov(n, n), res%corr(n, n), res%sigmas(n), res%flags(n), undetermined(n))
        call covariance(a, opts, res%cov, res%sigmas, res%corr, res%cond, res%rank, &
                        undetermined, stat)
        if (stat%code /= STATUS_OK) return
        call set_flags(res, params, lower, upper, undetermined, opts)
    end subroutine fit_at

    subroutine set_flags(res, params0, lower, upper, undetermined, opts)
        type(fit_result_t), intent(inout) :: res
        real(dp), intent(in) :: params0(:), lower(:), upper(:)
        logical, intent(in) :: undetermined(:)
        type(fit_options_t), intent(in) :: opts
        integer :: i, j, k, n
        real(dp) :: x, x0
        n = size(res%free)
        res%flags = FLAG_OK
        do i = 1, n
            k = res%free(i)
            x = res%estimates(i)
            x0 = params0(k)
            do j = 1, n
                if (j /= i .and. .not. ieee_is_nan(res%corr(i, j))) then
                    if (abs(res%corr(i, j)) > opts%corr_limit) res%flags(i) = FLAG_CORRELATED
                end if
            end do
            if (x <= lower(k) .or. x >= upper(k)) res%flags(i) = FLAG_AT_BOUND
            if (ran_away(x, x0, lower(k), opts)) res%flags(i) = FLAG_RUNAWAY
            if (undetermined(i)) then
                res%flags(i) = FLAG_UNDETERMINED
            else if (x /= 0.0_dp .and. res%sigmas(i) > abs(x) .and. &
                     res%flags(i) /= FLAG_AT_BOUND) then
                res%flags(i) = FLAG_UNDETERMINED
            end if
        end do
    end subroutine set_flags

    ! ------------------------------------------------------------- score test

    !> Score (Lagrange-multiplier) test of the parameter block `block`, held at
    !! its current values in `params` (the null), against a model whose
    !! parameters `free` have been fitted (params at the estimates).
    !!
    !! With the weighted Jacobian a = [a_F a_B] and weighted residuals r, the
    !! block's columns are projected off the span of a_F; the least-squares
    !! correction of the projected columns gives the first-order estimate
    !! delta = pinv(a_B_perp) r, its covariance and the predicted chi-square
    !! drop |a_B_perp delta|^2 (the LM statistic g^T I^-1 g). A parameter whose
    !! null value sits on a bound is one-sided: a first-order estimate pointing
    !! out of the box makes the block nonphysical, the offending parameters are
    !! removed one at a time (active set) and the drop is that of the rest.
    !! p-value: chi-square with the number of kept parameters, halved for a
    !! single one-sided parameter (chi-bar-square mixture).
    subroutine score_test(model, y, sigma, params, free, lower, upper, prior, block, opts, &
                          res, stat)
        class(residual_model_t), intent(inout) :: model
        real(dp), intent(in) :: y(:), sigma(:), params(:), lower(:), upper(:)
        integer, intent(in) :: free(:), block(:)
        type(prior_t), intent(in) :: prior
        type(fit_options_t), intent(in) :: opts
        type(score_result_t), intent(out) :: res
        type(status_t), intent(inout) :: stat
        integer :: m, mt, nf, nb, rf, k, j, worst
        integer, allocatable :: cols(:), side(:)
        real(dp), allocatable :: pred(:), a(:, :), rr(:), ab(:, :), d(:), s(:), u(:, :)
        real(dp), allocatable :: vt(:, :), cov(:, :), sig(:), corr(:, :), delta(:)
        real(dp) :: viol, worst_viol
        logical, allocatable :: und(:)

        m = size(y)
        mt = m + size(prior%index)
        nf = size(free)
        nb = size(block)
        res%params = block
        allocate (res%estimate(nb), res%sigma(nb), res%active(nb), res%direction(mt), &
                  res%free_step(nf))
        res%free_step = 0.0_dp
        res%estimate = 0.0_dp
        res%sigma = infinity()
        res%active = .true.
        res%direction = 0.0_dp
        cols = [free, block]
        allocate (pred(m), a(mt, nf + nb), rr(mt))
        call weighted_system(model, y, sigma, params, cols, prior, pred, a, rr, stat)
        if (stat%code /= STATUS_OK) return
        ab = a(:, nf + 1:)
        ! project the block's columns off the span of the free columns
        if (nf > 0) then
            rf = min(mt, nf)
            allocate (d(nf), s(rf), u(mt, rf), vt(rf, nf))
            call scaled_svd(a(:, 1:nf), d, s, u, vt, stat)
            if (stat%code /= STATUS_OK) return
            do k = 1, rf
                if (s(k) <= opts%rcond*s(1)) cycle
                do j = 1, nb
                    ab(:, j) = ab(:, j) - u(:, k)*dot_product(u(:, k), ab(:, j))
                end do
            end do
        end if
        do j = 1, nb
            if (norm2(ab(:, j)) <= 1.0e-8_dp*norm2(a(:, nf + j))) res%identifiable = .false.
        end do
        ! sign constraints from the bounds at the null value
        allocate (side(nb))
        do j = 1, nb
            side(j) = 0
            if (params(block(j)) <= lower(block(j))) side(j) = 1
            if (params(block(j)) >= upper(block(j))) side(j) = -1
        end do
        allocate (cov(nb, nb), sig(nb), corr(nb, nb), und(nb))
        call solve_block(res%active, delta, stat)
        if (stat%code /= STATUS_OK) return
        res%estimate = delta
        res%sigma = sig
        do j = 1, nb
            if (side(j) /= 0 .and. real(side(j), dp)*delta(j) < 0.0_dp) res%physical = .false.
            ! beyond the far bound (axial_coupling > 1) is not: the linear
            ! estimate overshoots when the base fit is far off, and the
            ! refit starts clipped to the bound
            if (ieee_is_finite(sig(j)) .and. side(j) == 0) then
                if (params(block(j)) + delta(j) > upper(block(j)) + 3.0_dp*sig(j) .or. &
                    params(block(j)) + delta(j) < lower(block(j)) - 3.0_dp*sig(j)) &
                    res%physical = .false.
            end if
        end do
        ! active set: drop one-sided parameters that point out of the box
        do
            worst = 0
            worst_viol = 0.0_dp
            do j = 1, nb
                if (.not. res%active(j) .or. side(j) == 0) cycle
                viol = real(side(j), dp)*delta(j)/max(sig(j), tiny(1.0_dp))
                if (viol < worst_viol) then
                    worst_viol = viol
                    worst = j
                end if
            end do
            if (worst == 0) exit
            res%active(worst) = .false.
            if (.not. any(res%active)) exit
            call solve_block(res%active, delta, stat)
            if (stat%code /= STATUS_OK) return
        end do
        res%dof = count(res%active)
        if (res%dof == 0 .or. .not. res%identifiable) then
            res%drop = 0.0_dp
            res%p_value = 1.0_dp
            return
        end if
        res%direction = matmul(ab, merge(delta, 0.0_dp, res%active))
        ! the free parameters' least-squares change with the block moved by delta
        if (nf > 0) res%free_step = lm_step(d, s, u, vt, &
            rr - matmul(a(:, nf + 1:), merge(delta, 0.0_dp, res%active)), 0.0_dp, opts%rcond)
        res%drop = sum(res%direction**2)
        if (norm2(res%direction) > 0.0_dp) res%direction = res%direction/norm2(res%direction)
        res%p_value = chi2_sf(res%drop, res%dof)
        if (res%dof == 1 .and. any(side /= 0 .and. res%active)) res%p_value = 0.5_dp*res%p_value

    contains

        !> Least-squares correction of the active projected columns.
        subroutine solve_block(active, dl, st)
            logical, intent(in) :: active(:)
            real(dp), allocatable, intent(out) :: dl(:)
            type(status_t), intent(inout) :: st
            integer :: na, rb, q, i
            integer, allocatable :: idx(:)
            real(dp), allocatable :: dd(:), ss(:), uu(:, :), vv(:, :), x(:)
            real(dp), allocatable :: cv(:, :), sg(:), cr(:, :)
            logical, allocatable :: un(:)
            real(dp) :: cn
            integer :: rk
            allocate (dl(nb))
            dl = 0.0_dp
            idx = pack([(i, i=1, nb)], active)
            na = size(idx)
            rb = min(mt, na)
            allocate (dd(na), ss(rb), uu(mt, rb), vv(rb, na), x(na))
            call scaled_svd(ab(:, idx), dd, ss, uu, vv, st)
            if (st%code /= STATUS_OK) return
            x = lm_step(dd, ss, uu, vv, rr, 0.0_dp, opts%rcond)
            allocate (cv(na, na), sg(na), cr(na, na), un(na))
            call covariance(ab(:, idx), opts, cv, sg, cr, cn, rk, un, st)
            if (st%code /= STATUS_OK) return
            do q = 1, na
                dl(idx(q)) = x(q)
                sig(idx(q)) = sg(q)
            end do
            if (rk < na) res%identifiable = .false.
        end subroutine solve_block
    end subroutine score_test

    ! ------------------------------------------------------------------ refits

    !> Refit `base` with the parameters `block` (an effect, at its null values
    !! in base) free as well, from starts that can converge when the base fit
    !! is far from the truth, keeping the best that converges:
    !! 1. START_SCORE: the first-order (score) estimate of the block with the
    !!    free parameters moved along with it (score%free_step), shortened by
    !!    halves while the model cannot be solved there;
    !! 2. START_NOMINAL: the nominal model (the free parameters at `nominal`,
    !!    the values the user started from), the block at its null values;
    !! 3. START_CONTINUATION: the block's strength stepped from its null value
    !!    to the first-order estimate in `ncont` steps, the free parameters
    !!    fitted at each, then everything freed.
    !! The best is the lowest chi-square among the starts that converge
    !! (STOP_CONVERGED; a later start must beat the best so far by more than
    !! 1e-6 of it, so the same minimum reached twice keeps the earlier start,
    !! whatever the nominal model). Starts after one whose chi-square is
    !! consistent with the noise (below dof + 3 sqrt(2 dof)) are skipped: no
    !! other minimum can be significantly better. `info%note` says what each start gave. When
    !! none converges, `res` is the lowest-cost attempt (flagged) and the
    !! status is ERR_NO_CONVERGENCE with the notes; a model that cannot be
    !! evaluated at base%params is an error as usual.
    subroutine refit_effect(model, y, sigma, base, block, score, nominal, null_values, lower, &
                            upper, prior, opts, res, info, stat, ncont, use, enough)
        class(residual_model_t), intent(inout) :: model
        real(dp), intent(in) :: y(:), sigma(:), nominal(:), null_values(:), lower(:), upper(:)
        type(fit_result_t), intent(in) :: base
        integer, intent(in) :: block(:)
        type(score_result_t), intent(in) :: score
        type(prior_t), intent(in) :: prior
        type(fit_options_t), intent(in) :: opts
        type(fit_result_t), intent(out) :: res
        type(refit_info_t), intent(out) :: info
        type(status_t), intent(inout) :: stat
        integer, intent(in), optional :: ncont  !< continuation steps (default 4)
        logical, intent(in), optional :: use(3) !< which starts to try (default all)
        !> stop at a converged start with half the predicted drop (default no)
        logical, intent(in), optional :: enough
        integer :: nf, nb, k, j, half, nsteps, kk
        logical :: try(3)
        integer, allocatable :: all_free(:)
        real(dp), allocatable :: target(:), start(:), shift(:), p(:)
        real(dp) :: best_cost, noise, t, base_cost, half_drop
        type(fit_result_t) :: trial, fallback, fixed
        type(status_t) :: st
        logical :: have_best, have_fallback, same
        character(len=:), allocatable :: why
        character(len=*), parameter :: label(3) = [character(len=27) :: &
            'from the first-order start', 'from the nominal model', 'by continuation']

        nf = size(base%free)
        nb = size(block)
        nsteps = 4
        if (present(ncont)) nsteps = max(ncont, 1)
        try = .true.
        if (present(use)) try = use
        base_cost = base%chi2 + base%chi2_prior
        half_drop = huge(1.0_dp)
        if (present(enough)) then
            if (enough .and. score%drop > 0.0_dp) half_drop = 0.5_dp*score%drop
        end if
        all_free = [base%free, block]
        info%note = ''
        info%start = START_NONE
        info%tried = 0
        have_best = .false.
        have_fallback = .false.
        best_cost = huge(1.0_dp)
        noise = huge(1.0_dp)
        if (base%dof - nb > 0) noise = real(base%dof - nb, dp) + &
                                       3.0_dp*sqrt(2.0_dp*real(base%dof - nb, dp))
        ! the first-order target of the block and the free parameters' shift
        target = null_values(block)
        allocate (shift(nf))
        shift = 0.0_dp
        if (allocated(score%estimate)) then
            if (size(score%estimate) == nb) then
                do j = 1, nb
                    if (score%active(j)) target(j) = null_values(block(j)) + score%estimate(j)
                end do
            end if
            if (allocated(score%free_step)) then
                if (size(score%free_step) == nf) shift = score%free_step
            end if
        end if

        ! 1. the first-order start, halved while the model cannot be solved there
        t = 1.0_dp
        if (try(1)) then
            do half = 0, 4
                start = base%params
                start(base%free) = base%params(base%free) + t*shift
                start(block) = null_values(block) + t*(target - null_values(block))
                call into_box(start)
                call clear_status(st)
                call fit_least_squares(model, y, sigma, start, all_free, lower, upper, prior, &
                                       opts, trial, st)
                if (allocated(trial%params) .or. st%code <= 0 .or. half == 4) exit
                t = 0.5_dp*t
            end do
            call consider(START_SCORE, trial, st, shortened=t < 1.0_dp)
            if (stat%code /= STATUS_OK) return
        end if

        ! 2. the nominal model with the effect at its null value
        if (try(2) .and. .not. done()) then
            start = base%params
            start(base%free) = nominal(base%free)
            start(block) = null_values(block)
            call into_box(start)
            same = try(1) .and. all(start == base%params) .and. all(shift == 0.0_dp) .and. &
                   all(target == null_values(block))
            if (.not. same) then
                call clear_status(st)
                call fit_least_squares(model, y, sigma, start, all_free, lower, upper, prior, &
                                       opts, trial, st)
                call consider(START_NOMINAL, trial, st)
                if (stat%code /= STATUS_OK) return
            end if
        end if

        ! 3. continuation in the effect's strength from its null value
        if (try(3) .and. .not. done() .and. any(target /= null_values(block))) then
            p = base%params
            kk = 0
            why = ''
            do k = 1, nsteps
                start = p
                start(block) = null_values(block) + real(k, dp)/real(nsteps, dp)* &
                               (target - null_values(block))
                call into_box(start)
                call clear_status(st)
                call fit_least_squares(model, y, sigma, start, base%free, lower, upper, prior, &
                                       opts, fixed, st)
                if (st%code /= STATUS_OK) then
                    why = trim(st%message)
                    exit
                end if
                if (fixed%stop /= STOP_CONVERGED .and. fixed%stop /= STOP_RUNAWAY) then
                    why = fixed%note
                    exit
                end if
                p = fixed%params
                kk = k
            end do
            if (kk > 0) then
                call clear_status(st)
                call fit_least_squares(model, y, sigma, p, all_free, lower, upper, prior, &
                                       opts, trial, st)
                call consider(START_CONTINUATION, trial, st)
                if (stat%code /= STATUS_OK) return
            else
                call add_note(trim(label(3))//': the first step could not be fitted ('// &
                              why//')')
            end if
        end if

        if (.not. have_best) then
            if (have_fallback) res = fallback
            call set_status(stat, ERR_NO_CONVERGENCE, 'refit', 'no start converged: '// &
                            info%note)
        end if

    contains

        !> Keep `trial` if it converged and beats the best so far.
        subroutine consider(which, tr, st1, shortened)
            integer, intent(in) :: which
            type(fit_result_t), intent(in) :: tr
            type(status_t), intent(in) :: st1
            logical, intent(in), optional :: shortened
            character(len=:), allocatable :: what
            real(dp) :: cost
            info%tried = info%tried + 1
            what = trim(label(which))
            if (present(shortened)) then
                if (shortened) what = what//' (shortened to '//fmt_real(t)//')'
            end if
            if (st1%code < 0) then
                ! bad input is bad input, whatever the start
                stat = st1
                return
            end if
            if (.not. allocated(tr%params)) then
                call add_note(what//': '//trim(st1%message))
                return
            end if
            cost = tr%chi2 + tr%chi2_prior
            if (st1%code == STATUS_OK .and. tr%stop == STOP_CONVERGED) then
                call add_note(what//': converged, chi-square '//fmt_real(tr%chi2))
                ! a later start must do better than the same minimum reached
                ! again (ties go to the earlier start)
                if (.not. have_best .or. &
                    cost < best_cost - 1.0e-6_dp*best_cost - 1.0e-9_dp) then
                    res = tr
                    best_cost = cost
                    have_best = .true.
                    info%start = which
                end if
            else
                if (allocated(tr%note)) then
                    call add_note(what//': '//tr%note)
                else
                    call add_note(what//': '//trim(st1%message))
                end if
                if (.not. have_best .and. .not. have_fallback) then
                    fallback = tr
                    have_fallback = .true.
                else if (.not. have_best) then
                    if (cost < fallback%chi2 + fallback%chi2_prior) fallback = tr
                end if
            end if
        end subroutine consider

        logical function done()
            done = have_best .and. (best_cost <= noise .or. base_cost - best_cost >= half_drop)
        end function done

        subroutine add_note(text)
            character(len=*), intent(in) :: text
            if (len(info%note) > 0) info%note = info%note//'; '
            info%note = info%note//text
        end subroutine add_note

        !> Clip into the bounds; a parameter bounded below by 0 (a
        !! stiffness, never 0 in the solver) keeps half its base value.
        subroutine into_box(q)
            real(dp), intent(inout) :: q(:)
            integer :: i, ip
            do i = 1, size(all_free)
                ip = all_free(i)
                q(ip) = min(max(q(ip), lower(ip)), upper(ip))
                if (lower(ip) == 0.0_dp .and. q(ip) <= 0.0_dp .and. base%params(ip) > 0.0_dp) &
                    q(ip) = 0.5_dp*base%params(ip)
            end do
        end subroutine into_box

    end subroutine refit_effect

    ! -------------------------------------------------------------- diagnosis

    !> Diagnose a fitted model (`base`, from fit_least_squares): score-test
    !! every candidate block whose parameters are all at their null values and
    !! not free, refit the `nrefit` leading physical candidates with their
    !! parameters freed (likelihood-ratio confirmation; refit_effect: from the
    !! first-order estimate, the nominal model and by continuation in the
    !! effect's strength, the best that converges; a candidate none of whose
    !! starts converges keeps refit_ok = .false. and the reasons in
    !! cand%info%note), rank, and pick the
    !! verdict: the best candidate whose refit is significant at alpha /
    !! (number tested) (Bonferroni), physical and determined. Candidates that
    !! explain the residuals about as well as the verdict (chi-square drops
    !! within ambiguity_delta, or nearly collinear directions) are marked as
    !! rivals (Akaike-style gains drop - 2 k within ambiguity_delta, or within
    !! twice that when the first-order directions are collinear); when `probe`
    !! is present, the probe row whose predictions
    !! differ most between the verdict's and a rival's refits (in units of
    !! probe_sigma) is reported as the measurement that would separate them.
    subroutine diagnose(model, y, sigma, base, null_values, lower, upper, prior, cands, &
                        fopts, dopts, diag, stat, probe, probe_sigma, nominal)
        class(residual_model_t), intent(inout) :: model
        real(dp), intent(in) :: y(:), sigma(:), null_values(:), lower(:), upper(:)
        type(fit_result_t), intent(in) :: base
        type(prior_t), intent(in) :: prior
        type(candidate_t), intent(in) :: cands(:)
        type(fit_options_t), intent(in) :: fopts
        type(diagnose_options_t), intent(in) :: dopts
        type(diagnosis_t), intent(out) :: diag
        type(status_t), intent(inout) :: stat
        class(residual_model_t), intent(inout), optional :: probe
        real(dp), intent(in), optional :: probe_sigma(:)
        real(dp), intent(in), optional :: nominal(:) !< starting values of the user's
        !! model, a start of the refits (default: base%params)
        integer :: nc, c, k, nrefit, best, q
        integer, allocatable :: order(:), tier(:)
        real(dp), allocatable :: key(:), pa(:), pb(:), jdummy(:, :)
        type(status_t) :: st
        real(dp) :: sep
        integer :: row

        nc = size(cands)
        allocate (diag%cand(nc), diag%cosine(nc, nc))
        diag%cosine = 0.0_dp
        diag%verdict = 0
        diag%ntested = 0
        do c = 1, nc
            associate (cr => diag%cand(c))
                if (size(cands(c)%params) == 0) then
                    cr%state = CAND_NO_PARAMS
                else if (any([(any(base%free == cands(c)%params(k)), &
                               k=1, size(cands(c)%params))])) then
                    cr%state = CAND_FREE
                else if (any(base%params(cands(c)%params) /= null_values(cands(c)%params))) then
                    cr%state = CAND_ACTIVE
                else
                    cr%state = CAND_TESTED
                    call score_test(model, y, sigma, base%params, base%free, lower, upper, &
                                    prior, cands(c)%params, fopts, cr%score, stat)
                    if (stat%code /= STATUS_OK) then
                        stat%message = trim(stat%message)//' (score test of '// &
                                       cands(c)%name//')'
                        return
                    end if
                    diag%ntested = diag%ntested + 1
                end if
            end associate
        end do
        diag%alpha_each = dopts%alpha/real(max(diag%ntested, 1), dp)
        do c = 1, nc
            do k = 1, nc
                if (diag%cand(c)%state == CAND_TESTED .and. &
                    diag%cand(k)%state == CAND_TESTED) diag%cosine(c, k) = &
                    dot_product(diag%cand(c)%score%direction, diag%cand(k)%score%direction)
            end do
        end do
        ! first pass: order by predicted drop, physical candidates first
        allocate (key(nc))
        do c = 1, nc
            key(c) = -huge(1.0_dp)
            if (diag%cand(c)%state /= CAND_TESTED) cycle
            key(c) = diag%cand(c)%score%drop
            if (.not. (diag%cand(c)%score%physical .and. diag%cand(c)%score%identifiable)) &
                key(c) = key(c) - 1.0e30_dp
        end do
        order = sort_desc(key)
        ! confirm the leading candidates by refits
        nrefit = 0
        do q = 1, nc
            c = order(q)
            if (nrefit >= dopts%nrefit) exit
            if (diag%cand(c)%state /= CAND_TESTED) cycle
            if (.not. (diag%cand(c)%score%physical .and. &
                       diag%cand(c)%score%identifiable)) cycle
            if (diag%cand(c)%score%drop <= 0.0_dp) cycle
            if (dopts%refit_significant_only .and. &
                .not. diag%cand(c)%score%p_value < dopts%alpha) cycle
            nrefit = nrefit + 1
            associate (cr => diag%cand(c))
                call clear_status(st)
                if (present(nominal)) then
                    call refit_effect(model, y, sigma, base, cands(c)%params, cr%score, nominal, &
                                      null_values, lower, upper, prior, fopts, cr%refit, &
                                      cr%info, st, use=dopts%starts, &
                                      enough=dopts%first_enough)
                else
                    call refit_effect(model, y, sigma, base, cands(c)%params, cr%score, &
                                      base%params, null_values, lower, upper, prior, fopts, &
                                      cr%refit, cr%info, st, use=dopts%starts, &
                                      enough=dopts%first_enough)
                end if
                if (st%code < 0) then
                    stat = st
                    return
                end if
                cr%refit_done = .true.
                cr%refit_ok = st%code == STATUS_OK
                if (cr%refit_ok) then
                    cr%lr_drop = (base%chi2 + base%chi2_prior) - &
                                 (cr%refit%chi2 + cr%refit%chi2_prior)
                    cr%lr_p = chi2_sf(max(cr%lr_drop, 0.0_dp), size(cands(c)%params))
                    if (size(cands(c)%params) == 1 .and. any(cr%score%active .and. &
                        (base%params(cands(c)%params) <= lower(cands(c)%params) .or. &
                         base%params(cands(c)%params) >= upper(cands(c)%params)))) &
                        cr%lr_p = 0.5_dp*cr%lr_p
                    cr%significant = cr%lr_p < diag%alpha_each
                    k = size(base%free)
                    ! a refit that returns the effect to its null value (a bound) or
                    ! cannot determine it is not an explanation; a bound away from
                    ! the null (axial_coupling = 1, the exact form) is
                    cr%acceptable = cr%significant .and. &
                                    all(cr%refit%flags(k + 1:) /= FLAG_UNDETERMINED) .and. &
                                    all(cr%refit%flags(k + 1:) /= FLAG_RUNAWAY) .and. &
                                    any(cr%refit%params(cands(c)%params) /= &
                                        null_values(cands(c)%params))
                else
                    cr%lr_drop = not_a_number()
                    cr%lr_p = not_a_number()
                end if
            end associate
        end do
        ! final ranking in tiers: acceptable refits, other refits, physical score
        ! tests, the rest; within a tier by the Akaike-style gain drop - 2 dof
        ! (refits: actual drop, otherwise the predicted one)
        allocate (tier(nc))
        do c = 1, nc
            tier(c) = 0
            if (diag%cand(c)%state /= CAND_TESTED) cycle
            key(c) = diag%cand(c)%score%drop - 2.0_dp*diag%cand(c)%score%dof
            tier(c) = 1
            if (diag%cand(c)%score%physical .and. diag%cand(c)%score%identifiable) tier(c) = 2
            if (diag%cand(c)%refit_done .and. diag%cand(c)%refit_ok) then
                key(c) = diag%cand(c)%lr_drop - 2.0_dp*size(cands(c)%params)
                tier(c) = 3
                if (diag%cand(c)%acceptable) tier(c) = 4
            end if
        end do
        diag%ranking = sort_desc(key, tier)
        best = 0
        do q = 1, nc
            c = diag%ranking(q)
            if (diag%cand(c)%acceptable) then
                best = c
                exit
            end if
        end do
        diag%verdict = best
        if (best == 0) return
        ! rivals: explain the residuals about as well as the verdict
        do c = 1, nc
            if (c == best .or. .not. diag%cand(c)%acceptable) cycle
            if ((diag%cand(best)%lr_drop - 2.0_dp*size(cands(best)%params)) - &
                (diag%cand(c)%lr_drop - 2.0_dp*size(cands(c)%params)) < &
                dopts%ambiguity_delta .or. (abs(diag%cosine(best, c)) > dopts%collinear &
                .and. (diag%cand(best)%lr_drop - 2.0_dp*size(cands(best)%params)) - &
                (diag%cand(c)%lr_drop - 2.0_dp*size(cands(c)%params)) < &
                2.0_dp*dopts%ambiguity_delta)) diag%cand(c)%rival = .true.
        end do
        if (.not. present(probe) .or. .not. present(probe_sigma)) return
        if (.not. any(diag%cand%rival)) return
        allocate (pa(size(probe_sigma)), pb(size(probe_sigma)), jdummy(size(probe_sigma), 0))
        call probe%evaluate(diag%cand(best)%refit%params, [integer ::], pa, jdummy, stat)
        if (stat%code /= STATUS_OK) return
        do c = 1, nc
            if (.not. diag%cand(c)%rival) cycle
            call probe%evaluate(diag%cand(c)%refit%params, [integer ::], pb, jdummy, stat)
            if (stat%code /= STATUS_OK) return
            row = maxloc(abs(pa - pb)/probe_sigma, 1)
            sep = abs(pa(row) - pb(row))/probe_sigma(row)
            diag%cand(c)%separating_row = row
            diag%cand(c)%separation = sep
        end do
    end subroutine diagnose

    !> Indices that sort by `tier` then `key`, both descending (stable
    !! insertion sort; without tiers by key alone).
    pure function sort_desc(key, tier) result(order)
        real(dp), intent(in) :: key(:)
        integer, intent(in), optional :: tier(:)
        integer :: order(size(key))
        integer :: i, j, t
        integer :: tr(size(key))
        tr = 0
        if (present(tier)) tr = tier
        order = [(i, i=1, size(key))]
        do i = 2, size(key)
            t = order(i)
            j = i - 1
            do while (j >= 1)
                if (tr(order(j)) > tr(t)) exit
                if (tr(order(j)) == tr(t) .and. key(order(j)) >= key(t)) exit
                order(j + 1) = order(j)
                j = j - 1
            end do
            order(j + 1) = t
        end do
    end function sort_desc

    ! ------------------------------------------------------------ statistics

    !> Tests for systematic structure in normalized residuals (compare):
    !! a Wald-Wolfowitz runs test on the signs of the residuals ordered by load
    !! level within each quantity group (groups in order of first appearance,
    !! concatenated; zero residuals skipped), one-sided: few runs (long
    !! same-sign stretches) mean structure; and the least-squares slope of the
    !! normalized residuals against load level, whose z under pure noise is
    !! slope * sqrt(sum (x - mean x)^2). Undefined results are NaN.
    !! out = [runs, expected runs, runs z, runs p, slope, trend z, trend p].
    pure subroutine residual_structure(level, group, normalized, out)
        real(dp), intent(in) :: level(:), normalized(:)
        integer, intent(in) :: group(:)
        real(dp), intent(out) :: out(7)
        integer :: n, i, j, k, g, nsign, n1, n2, runs, t
        integer, allocatable :: order(:), signs(:)
        logical, allocatable :: seen(:)
        real(dp) :: mean, var, z, xbar, sxx, sxy, nn

        out = not_a_number()
        n = size(normalized)
        allocate (order(n), signs(n), seen(n))
        seen = .false.
        nsign = 0
        do i = 1, n
            if (seen(i)) cycle
            g = group(i)
            ! rows of this group in their original order, then a stable sort by level
            k = 0
            do j = i, n
                if (group(j) == g) then
                    seen(j) = .true.
                    k = k + 1
                    order(k) = j
                end if
            end do
            do j = 2, k
                t = order(j)
                call insert_sorted(order, j, t)
            end do
            do j = 1, k
                if (normalized(order(j)) /= 0.0_dp) then
                    nsign = nsign + 1
                    signs(nsign) = merge(1, 0, normalized(order(j)) > 0.0_dp)
                end if
            end do
        end do
        n1 = sum(signs(1:nsign))
        n2 = nsign - n1
        if (n1 > 0 .and. n2 > 0) then
            runs = 1 + count(signs(2:nsign) /= signs(1:nsign - 1))
            nn = real(nsign, dp)
            mean = 2.0_dp*n1*n2/nn + 1.0_dp
            var = 0.0_dp
            if (nsign > 1) var = 2.0_dp*n1*n2*(2.0_dp*n1*n2 - nn)/(nn*nn*(nn - 1.0_dp))
            z = 0.0_dp
            if (var > 0.0_dp) z = (real(runs, dp) - mean)/sqrt(var)
            out(1) = real(runs, dp)
            out(2) = mean
            out(3) = z
            if (z < 0.0_dp) then
                out(4) = 0.5_dp*chi2_sf(z*z, 1)
            else
                out(4) = 1.0_dp - 0.5_dp*chi2_sf(z*z, 1)
            end if
        end if
        if (n >= 3) then
            if (maxval(level) > minval(level)) then
                xbar = sum(level)/real(n, dp)
                sxx = sum((level - xbar)**2)
                sxy = sum((level - xbar)*normalized)
                out(5) = sxy/sxx
                out(6) = out(5)*sqrt(sxx)
                out(7) = chi2_sf(out(6)**2, 1)
            end if
        end if

    contains

        !> Insert order(j) = t into the level-sorted order(1:j-1) (stable).
        pure subroutine insert_sorted(idx, j, t)
            integer, intent(inout) :: idx(:)
            integer, intent(in) :: j, t
            integer :: m
            m = j - 1
            do while (m >= 1)
                if (level(idx(m)) <= level(t)) exit
                idx(m + 1) = idx(m)
                m = m - 1
            end do
            idx(m + 1) = t
        end subroutine insert_sorted
    end subroutine residual_structure

    !> Chi-square survival function P(X > x) for k degrees of freedom: the
    !! regularized upper incomplete gamma function Q(k/2, x/2), by its series
    !! for x < a + 1 and by its continued fraction (modified Lentz) otherwise.
    pure real(dp) function chi2_sf(x, k)
        real(dp), intent(in) :: x
        integer, intent(in) :: k
        real(dp) :: a, z
        if (k <= 0) then
            chi2_sf = 1.0_dp
            return
        end if
        if (ieee_is_nan(x)) then
            chi2_sf = not_a_number()
            return
        end if
        if (x <= 0.0_dp) then
            chi2_sf = 1.0_dp
            return
        end if
        a = 0.5_dp*real(k, dp)
        z = 0.5_dp*x
        if (z < a + 1.0_dp) then
            chi2_sf = max(0.0_dp, 1.0_dp - gamma_p_series(a, z))
        else
            chi2_sf = gamma_q_fraction(a, z)
        end if
    end function chi2_sf

    pure real(dp) function gamma_p_series(a, z)
        real(dp), intent(in) :: a, z
        real(dp) :: term, total, ap
        integer :: n
        ap = a
        term = 1.0_dp/a
        total = term
        do n = 1, 1000
            ap = ap + 1.0_dp
            term = term*z/ap
            total = total + term
            if (abs(term) < abs(total)*1.0e-16_dp) exit
        end do
        gamma_p_series = total*exp(-z + a*log(z) - log_gamma(a))
    end function gamma_p_series

    pure real(dp) function gamma_q_fraction(a, z)
        real(dp), intent(in) :: a, z
        real(dp), parameter :: small = 1.0e-300_dp
        real(dp) :: b, c, d, h, an, del
        integer :: i
        b = z + 1.0_dp - a
        c = 1.0_dp/small
        d = 1.0_dp/b
        h = d
        do i = 1, 1000
            an = -real(i, dp)*(real(i, dp) - a)
            b = b + 2.0_dp
            d = an*d + b
            if (abs(d) < small) d = small
            c = b + an/c
            if (abs(c) < small) c = small
            d = 1.0_dp/d
            del = d*c
            h = h*del
            if (abs(del - 1.0_dp) < 1.0e-16_dp) exit
        end do
        gamma_q_fraction = exp(-z + a*log(z) - log_gamma(a))*h
    end function gamma_q_fraction
end module beamid_estimation
