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
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan
    use beamid_kinds, only: dp, infinity, not_a_number
    use beamid_status, only: status_t, set_status, clear_status, STATUS_OK, ERR_INPUT, &
                             ERR_NO_CONVERGENCE, ERR_NUMERIC, fmt_int, fmt_real
    use beamid_lapack, only: svd_thin
    implicit none
    private

    public :: residual_model_t, prior_t, lsq_problem_t, fit_options_t, fit_result_t
    public :: score_result_t, candidate_t, diagnose_options_t, candidate_report_t
    public :: diagnosis_t, refit_info_t
    public :: fit_least_squares, fit_at, score_test, diagnose, chi2_sf, residual_structure
    public :: refit_effect, prior_from_covariance, sort_desc

    !> Per-parameter flags of a fit (worst first).
    integer, parameter, public :: FLAG_OK = 0           !< determined
    integer, parameter, public :: FLAG_UNDETERMINED = 1 !< infinite or > 100 % sigma
    integer, parameter, public :: FLAG_RUNAWAY = 2      !< moved by more than runaway_factor
    integer, parameter, public :: FLAG_CORRELATED = 3   !< |correlation| above corr_limit
    integer, parameter, public :: FLAG_AT_BOUND = 4     !< estimate sits on a bound
    integer, parameter, public :: FLAG_WEAK = 5         !< sigma above WEAK_RELATIVE_SIGMA
    !! of |estimate| (but below 100 %): determined, poorly
    !! priority when several apply: undetermined, runaway, at bound, correlated, weak
    !> A determined estimate whose sigma exceeds this fraction of its value is
    !! flagged FLAG_WEAK ("weak"): docs/workflow.md, section 1 (the flags).
    real(dp), parameter, public :: WEAK_RELATIVE_SIGMA = 0.2_dp

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
    !> Relative noise floor of an integrated response's chi-square (noise_floor).
    real(dp), parameter :: FLOOR_REL = 1.0e-5_dp
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
    character(len=*), parameter, public :: FLAG_NAMES(0:5) = [character(len=43) :: 'ok', &
        'not determined by these data', 'ran away from its start', &
        'correlation near +-1 with another parameter', 'at a physical bound', 'weak']
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

    !> What every fit, score test, refit and diagnosis of one data set
    !! shares: the data rows y and their sigmas, the box lower <= p <= upper,
    !! the null values of the parameters (every effect switched off) and the
    !! a priori information. Built once by the caller; the model is passed
    !! beside it, since the same data are fitted through wrappers of a model
    !! (one-sided columns at the null, cached sensitivities, a finer mesh).
    type :: lsq_problem_t
        real(dp), allocatable :: y(:), sigma(:), lower(:), upper(:), nulls(:)
        type(prior_t) :: prior
    end type lsq_problem_t

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
        !> a fit with the measurement chain's row treatments (beamid_chain_fit;
        !! unallocated otherwise): per row the sigma it was judged with
        !! (estimated where asked), its last weight (0: burn-in) and whether
        !! it is a gross error
        real(dp), allocatable :: row_sigma(:), row_weight(:), row_sigma_sd(:)
        logical, allocatable :: row_gross(:)
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
        !> the continuation start only when neither earlier start converged
        !! (releases: five fits with sensitivities, paid only for a base fit
        !! too far off for the first-order and the nominal start; issue 30)
        logical :: continue_if_none = .false.
    end type diagnose_options_t

    !> How a refit with an effect switched on went (refit_effect).
    type :: refit_info_t
        integer :: start = START_NONE       !< START_* of the refit kept
        integer :: tried = 0                !< starts tried
        character(len=:), allocatable :: note !< per start: what happened
    end type refit_info_t

    !> The starts of refit_effect, in words (its notes).
    character(len=*), parameter :: REFIT_LABEL(3) = [character(len=27) :: &
        'from the first-order start', 'from the nominal model', 'by continuation']

    !> What refit_effect's starts share: the best converged refit's cost,
    !! the lowest-cost attempt while none converged, and when to stop.
    type :: refit_state_t
        logical :: have_best = .false., have_fallback = .false.
        real(dp) :: best_cost = huge(1.0_dp)
        real(dp) :: noise = huge(1.0_dp)      !< a chi-square consistent with the noise
        real(dp) :: base_cost = 0.0_dp        !< of the fit refitted
        real(dp) :: half_drop = huge(1.0_dp)  !< enough gain (first_enough)
        type(fit_result_t) :: fallback
    end type refit_state_t

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

    !> The working state of fit_least_squares, shared by its steps.
    type :: gn_state_t
        integer :: m = 0, n = 0, mt = 0    !< data rows, free parameters, rows + priors
        integer :: it0 = 1                 !< first iteration of the current phase
        integer :: level = ROUGH_OFF       !< roughness of the phase being confirmed
        integer :: nstuck = 0              !< damped steps in a row that moved nothing
        integer, allocatable :: free(:)    !< the problem: free parameters, start, box
        real(dp), allocatable :: p0(:), lower(:), upper(:)
        real(dp), allocatable :: p(:), pred(:), a(:, :), rr(:)    !< the iterate
        real(dp), allocatable :: pt(:), predt(:), at(:, :), rt(:) !< a trial step
        !> the projected Jacobian, gradient, its scaled SVD, the step
        real(dp), allocatable :: aa(:, :), g(:), d(:), s(:), u(:, :), vt(:, :), dx(:)
        logical, allocatable :: held(:)    !< ran away: held where found
        real(dp) :: cost = 0.0_dp, cost_t = 0.0_dp     !< at the iterate, at the trial
        real(dp) :: lambda = 0.0_dp, lambda_in = 0.0_dp, lam_floor = 0.0_dp
        real(dp) :: relstep = 0.0_dp, dcost = 0.0_dp  !< of the last step
        real(dp) :: pred_gn = 0.0_dp, pred_step = 0.0_dp
        logical :: stalled = .false., stall_pending = .false., poor_step = .false.
        !> poor steps in a row that gained less than floor_chi2 (at_minimum)
        integer :: nfloor = 0
        !> the model is an integrated response (releases: plain_trials)
        logical :: integrated = .false.
        logical :: failed_trial = .false.
        type(status_t) :: fail_stat        !< the model's message at the last failed trial
    end type gn_state_t

contains

    ! ----------------------------------------------------------------- helpers

    !> Weighted system at `params`: rows (y - f)/sigma then a priori rows;
    !! a = d f / d params(cols) / sigma, prior rows 1/sigma_prior.
    subroutine weighted_system(model, lp, params, cols, pred, a, r, stat)
        class(residual_model_t), intent(inout) :: model
        type(lsq_problem_t), intent(in) :: lp
        real(dp), intent(in) :: params(:)
        integer, intent(in) :: cols(:)
        real(dp), intent(out) :: pred(:), a(:, :), r(:)
        type(status_t), intent(inout) :: stat
        integer :: m, i, j
        real(dp), allocatable :: jac(:, :)
        m = size(lp%y)
        allocate (jac(m, size(cols)))
        call model%evaluate(params, cols, pred, jac, stat)
        if (stat%code /= STATUS_OK) return
        if (.not. (all(ieee_is_finite(pred)) .and. all(ieee_is_finite(jac)))) then
            call set_status(stat, ERR_NUMERIC, 'estimation', 'model returned non-finite '// &
                            'predictions or sensitivities')
            return
        end if
        do j = 1, size(cols)
            a(1:m, j) = jac(:, j)/lp%sigma
        end do
        r(1:m) = (lp%y - pred)/lp%sigma
        a(m + 1:, :) = 0.0_dp
        if (allocated(lp%prior%whiten)) then
            r(m + 1:) = matmul(lp%prior%whiten, lp%prior%mean - params(lp%prior%index))
            do i = 1, size(lp%prior%index)
                do j = 1, size(cols)
                    if (cols(j) == lp%prior%index(i)) a(m + 1:, j) = lp%prior%whiten(:, i)
                end do
            end do
            return
        end if
        do i = 1, size(lp%prior%index)
            r(m + i) = (lp%prior%mean(i) - params(lp%prior%index(i)))/lp%prior%sigma(i)
            do j = 1, size(cols)
                if (cols(j) == lp%prior%index(i)) a(m + i, j) = 1.0_dp/lp%prior%sigma(i)
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

    !> The first problem with the data, bounds, free parameters and prior, in
    !! that order, as an ERR_INPUT status of 'fit'.
    subroutine check_problem(lp, params, free, stat)
        type(lsq_problem_t), intent(in) :: lp
        real(dp), intent(in) :: params(:)
        integer, intent(in) :: free(:)
        type(status_t), intent(inout) :: stat
        character(len=:), allocatable :: problem
        integer :: i, np, k
        associate (y => lp%y, sigma => lp%sigma, lower => lp%lower, upper => lp%upper, &
                   prior => lp%prior)
        np = size(params)
        problem = ''
        if (size(sigma) /= size(y)) then
            problem = 'sigma has '//fmt_int(size(sigma))//' values for '//fmt_int(size(y))// &
                      ' data rows'
        else if (size(y) == 0) then
            problem = 'no data rows'
        end if
        do i = 1, size(y)
            if (len(problem) > 0) exit
            if (.not. ieee_is_finite(y(i))) then
                problem = 'data row '//fmt_int(i)//' value = '//fmt_real(y(i))// &
                          ', expected a finite number'
            else if (.not. (sigma(i) > 0.0_dp .and. ieee_is_finite(sigma(i)))) then
                problem = 'data row '//fmt_int(i)//' sigma = '//fmt_real(sigma(i))// &
                          ', expected sigma > 0'
            end if
        end do
        if (len(problem) == 0 .and. (size(lower) /= np .or. size(upper) /= np)) &
            problem = 'bounds do not match the parameter vector'
        if (len(problem) == 0 .and. size(free) == 0) &
            problem = 'no free parameters: name at least one'
        do i = 1, size(free)
            if (len(problem) > 0) exit
            k = free(i)
            if (k < 1 .or. k > np) then
                problem = 'free parameter index '//fmt_int(k)//' outside 1..'//fmt_int(np)
            else if (count(free == k) > 1) then
                problem = 'free parameter index '//fmt_int(k)//' given twice'
            else if (params(k) < lower(k) .or. params(k) > upper(k)) then
                problem = 'starting value of parameter '//fmt_int(k)//' = '// &
                          fmt_real(params(k))//' is outside its bounds ['// &
                          fmt_real(lower(k))//', '//fmt_real(upper(k))//']'
            end if
        end do
        if (len(problem) == 0 .and. (size(prior%mean) /= size(prior%index) .or. &
                                     size(prior%sigma) /= size(prior%index))) &
            problem = 'prior index, mean and sigma differ in size'
        do i = 1, size(prior%index)
            if (len(problem) > 0) exit
            k = prior%index(i)
            if (.not. any(free == k)) then
                problem = 'a priori parameter '//fmt_int(k)//' is not free'
            else if (.not. (prior%sigma(i) > 0.0_dp .and. ieee_is_finite(prior%sigma(i)))) then
                problem = 'a priori sigma of parameter '//fmt_int(k)//' = '// &
                          fmt_real(prior%sigma(i))//', expected sigma > 0'
            else if (.not. ieee_is_finite(prior%mean(i))) then
                problem = 'a priori mean of parameter '//fmt_int(k)//' is not finite'
            end if
        end do
        if (len(problem) > 0) call set_status(stat, ERR_INPUT, 'fit', problem)
        end associate
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
    subroutine fit_least_squares(model, lp, params0, free, opts, res, stat)
        class(residual_model_t), intent(inout) :: model
        type(lsq_problem_t), intent(in) :: lp
        real(dp), intent(in) :: params0(:)
        integer, intent(in) :: free(:)
        type(fit_options_t), intent(in) :: opts
        type(fit_result_t), intent(out) :: res
        type(status_t), intent(inout) :: stat
        type(gn_state_t) :: w
        integer :: it
        logical :: go_on, accepted, evaluated

        call check_problem(lp, params0, free, stat)
        if (stat%code /= STATUS_OK) return
        w = gn_state_t(free=free, p0=params0, lower=lp%lower, upper=lp%upper)
        call start_search(model, lp, params0, free, opts, w, res, stat)
        if (stat%code /= STATUS_OK) return
        ! phases: iterate (on the rough model, then steered by rough
        ! Jacobians, when the model offers them), confirm at the final point
        ! with the accurate model and iterate on, one level less rough, while
        ! it promises more than the noise floor (the inner loop's body is the
        ! one Gauss-Newton step)
        phases: do
        iterate: do it = w%it0, opts%max_iter
            call projected_svd(w, opts, stat)
            if (stat%code /= STATUS_OK) then
                model%rough = ROUGH_OFF
                return
            end if
            w%lam_floor = 1.0e-6_dp*w%s(1)**2
            w%pred_gn = predicted_decrease(w%s, w%u, w%rr, opts%rcond)
            if (at_minimum(w, it, model%rough, opts)) then
                res%converged = .true.
                res%iterations = it - 1
                exit
            end if
            if (w%stall_pending) then
                res%iterations = it - 1
                w%stalled = .true.
                exit
            end if
            call damped_trials(model, lp, opts, w, accepted, evaluated)
            res%iterations = it
            if (.not. accepted) then
                ! no damped step lowers the cost: a minimum to working precision
                ! when the smallest trial step could be evaluated; a stall when
                ! it could not (the model could not be solved at the fit's own
                ! trial parameters, however short the step: the fit comes back at
                ! its last good point, flagged, with the solver's message)
                if (w%failed_trial .or. .not. evaluated) then
                    w%stalled = .true.
                else
                    res%converged = .true.
                end if
                exit
            end if
            call take_step(w, it, res)
            if (w%lambda == 0.0_dp .and. (w%relstep < opts%tol_step .or. &
                w%dcost <= opts%tol_cost*w%cost_t .or. w%cost_t <= 1.0e-18_dp*w%mt)) then
                w%cost = w%cost_t
                res%converged = .true.
                exit
            end if
            call count_stuck_steps(w, it, res, opts)
            if (w%nstuck >= 3) then
                ! a stall unless the next iterate's test finds the noise floor
                if (it == opts%max_iter) then
                    w%stalled = .true.
                    exit
                end if
                w%stall_pending = .true.
            end if
            w%lambda = w%lambda/10.0_dp
            if (w%lambda < w%lam_floor) w%lambda = 0.0_dp
            call hold_runaways(w, opts)
            if (all(w%held)) exit
        end do iterate
        if (model%rough == ROUGH_OFF) exit phases
        w%level = model%rough
        call confirm_at_final_point(model, lp, opts, w, res%iterations, go_on, stat)
        if (stat%code /= STATUS_OK) return
        if (.not. go_on) exit phases
        model%rough = w%level - 1
        call restart_phase(w, res)
        end do phases
        call store_result(w, opts, res, stat)
        if (stat%code /= STATUS_OK) return   ! the model failed at every trial step
        call describe_ending(w, opts, res, stat)
    end subroutine fit_least_squares

    !> fit_least_squares' first step: the work arrays, the weighted system at
    !! the start (on the rough model when the model has one, at the user's
    !! tolerance when that cannot be solved) and the log's entry 0.
    subroutine start_search(model, lp, params0, free, opts, w, res, stat)
        class(residual_model_t), intent(inout) :: model
        type(lsq_problem_t), intent(in) :: lp
        real(dp), intent(in) :: params0(:)
        integer, intent(in) :: free(:)
        type(fit_options_t), intent(in) :: opts
        type(gn_state_t), intent(inout) :: w
        type(fit_result_t), intent(inout) :: res
        type(status_t), intent(inout) :: stat
        integer :: m, n, mt, r
        m = size(lp%y)
        n = size(free)
        mt = m + size(lp%prior%index)
        r = min(mt, n)
        w%m = m
        w%n = n
        w%mt = mt
        allocate (w%pred(m), w%predt(m), w%a(mt, n), w%at(mt, n), w%rr(mt), w%rt(mt))
        allocate (w%d(n), w%s(r), w%u(mt, r), w%vt(r, n), w%dx(n), w%held(n))
        allocate (res%log_cost(0:opts%max_iter), res%log_lambda(0:opts%max_iter), &
                  res%log_step(0:opts%max_iter), res%log_params(n, 0:opts%max_iter))
        res%free = free
        w%p = params0
        w%integrated = model%plain_trials
        ! the search starts on the rough model when the model has one
        ! (confirm_at_final_point makes each phase's end point accurate)
        model%rough = ROUGH_OFF
        if (model%rough_jacobian_ok) model%rough = ROUGH_ALL
        call weighted_system(model, lp, w%p, free, w%pred, w%a, w%rr, stat)
        if (stat%code /= STATUS_OK .and. model%rough == ROUGH_ALL) then
            ! not solvable at the rough tolerance: start at the user's
            call clear_status(stat)
            model%rough = ROUGH_JACOBIAN
            call weighted_system(model, lp, w%p, free, w%pred, w%a, w%rr, stat)
        end if
        if (stat%code /= STATUS_OK) then
            model%rough = ROUGH_OFF
            stat%message = trim(stat%message)//' (at the starting values)'
            return
        end if
        w%cost = sum(w%rr**2)
        res%nlog = 0
        res%log_cost(0) = w%cost
        res%log_lambda(0) = 0.0_dp
        res%log_step(0) = 0.0_dp
        res%log_params(:, 0) = w%p(free)
        w%lambda = 0.0_dp
        res%converged = .false.
        res%stop = STOP_MAX_ITER
        w%held = .false.
    end subroutine start_search

    !> Projected Gauss-Newton: a parameter on a bound whose descent
    !! direction (a^T r) points out of the box is held for this step, a
    !! parameter that ran away for good; w%aa = w%a without their columns and
    !! its scaled SVD (d, s, u, vt).
    subroutine projected_svd(w, opts, st)
        type(gn_state_t), intent(inout) :: w
        type(fit_options_t), intent(in) :: opts
        type(status_t), intent(inout) :: st
        integer :: i, k, nbound
        associate (free => w%free, lower => w%lower, upper => w%upper)
        w%aa = w%a
        w%g = matmul(w%rr, w%a)
        do i = 1, w%n
            if (w%held(i) .or. (w%p(free(i)) <= lower(free(i)) .and. w%g(i) < 0.0_dp) .or. &
                (w%p(free(i)) >= upper(free(i)) .and. w%g(i) > 0.0_dp)) w%aa(:, i) = 0.0_dp
        end do
        call scaled_svd(w%aa, w%d, w%s, w%u, w%vt, st)
        if (st%code /= STATUS_OK) return
        ! ... and one on a bound that the Gauss-Newton step would push out
        ! of the box (a clipped step would crawl along the bound)
        do k = 1, w%n
            w%dx = lm_step(w%d, w%s, w%u, w%vt, w%rr, 0.0_dp, opts%rcond)
            nbound = 0
            do i = 1, w%n
                if (all(w%aa(:, i) == 0.0_dp)) cycle
                if ((w%p(free(i)) <= lower(free(i)) .and. w%dx(i) < 0.0_dp) .or. &
                    (w%p(free(i)) >= upper(free(i)) .and. w%dx(i) > 0.0_dp)) then
                    w%aa(:, i) = 0.0_dp
                    nbound = nbound + 1
                end if
            end do
            if (nbound == 0) exit
            call scaled_svd(w%aa, w%d, w%s, w%u, w%vt, st)
            if (st%code /= STATUS_OK) return
        end do
        end associate
    end subroutine projected_svd

    !> The cost's noise floor: floor_chi2, and for an integrated response
    !! FLOOR_REL of the cost when that is more (issue 30, long records: the
    !! integrator's relative error makes the chi-square of a long record
    !! rough at ~1e-5 of itself, where steps of 0.01 are no longer
    !! judged; beamid.robust.same_chi2 is the same rule). Below a
    !! chi-square of 1000 it is floor_chi2.
    pure real(dp) function noise_floor(w, opts)
        type(gn_state_t), intent(in) :: w
        type(fit_options_t), intent(in) :: opts
        noise_floor = opts%floor_chi2
        if (w%integrated) noise_floor = max(noise_floor, FLOOR_REL*w%cost)
    end function noise_floor

    !> The decrease a step must promise to be judged against the cost's
    !! noise: noise_floor scaled by the misfit (chi-square per degree of
    !! freedom, at most 1), so that with (nearly) exact data the fit still
    !! goes on to the accurate minimum (confirm_at_final_point's rule after
    !! the rough model's phase).
    pure real(dp) function judged_floor(w, opts)
        type(gn_state_t), intent(in) :: w
        type(fit_options_t), intent(in) :: opts
        judged_floor = noise_floor(w, opts)*min(1.0_dp, w%cost/max(w%mt - w%n, 1))
    end function judged_floor

    !> Is iteration `it` at a minimum, before its step (w%pred_gn set)?
    pure logical function at_minimum(w, it, rough, opts)
        type(gn_state_t), intent(in) :: w
        integer, intent(in) :: it, rough
        type(fit_options_t), intent(in) :: opts
        ! first-order optimality: the undamped step would lower the cost by
        ! pred_gn = |U^T r|^2 = dx^T (A^T A) dx, the squared length of the
        ! step in units of the parameters' covariance (Eq. 55), so that
        ! |dx_i| <= sqrt(pred_gn) sigma_i for every parameter. Converged when
        ! that is negligible against the cost, or the data are matched to
        ! 1e-9 sigma a row (exact synthetic data)
        at_minimum = w%pred_gn <= opts%tol_cost*w%cost + tiny(1.0_dp) .or. &
                     w%cost <= 1.0e-18_dp*w%mt
        if (at_minimum) return
        ! the cost's noise floor: the last step had to be damped or gained
        ! less than a quarter of its linear prediction (the model is not
        ! smooth at this scale: an integrated response's switching events,
        ! its error control), it lowered the chi-square by less than
        ! floor_chi2 and the next step promises less than floor_chi2 more:
        ! what is left to gain has no statistical meaning
        at_minimum = it > 1 .and. w%poor_step .and. w%dcost <= noise_floor(w, opts) .and. &
                     w%pred_gn <= noise_floor(w, opts)
        if (at_minimum) return
        ! a rough phase's own noise floor (issue 30): its Jacobian carries the
        ! rough sensitivities' error (a few per cent of each column), and
        ! against residuals of the data's size that error alone predicts a
        ! decrease growing with the number of rows, so on long records pred_gn
        ! stays above floor_chi2 at the minimum and the search crawls in
        ! damped steps that gain nothing (2.5 s at 500 Hz: seven of eleven
        ! iterations). The phase ends after two poor steps in a row that each
        ! gained less than floor_chi2 (w%nfloor); confirm_at_final_point then
        ! judges the accurate decrease and goes on, one level less rough,
        ! while it promises more. The accurate phase of an integrated
        ! response ends there too: at 5 s and more, the friction switches
        ! leave pred_gn above floor_chi2 where steps no longer gain it.
        at_minimum = (rough /= ROUGH_OFF .or. w%integrated) .and. it > 1 .and. w%nfloor >= 2
        if (at_minimum) return
        ! a rough phase whose next step promises less than the noise floor
        ! (issue 30, cost on long records): the step cannot be judged (on a
        ! 10 s record at 500 Hz it failed, and sixteen damped trials of one
        ! plain run each, half the last window's cost, failed after it);
        ! confirm_at_final_point judges the accurate decrease and goes on,
        ! one level less rough, while it promises more
        at_minimum = rough /= ROUGH_OFF .and. w%pred_gn <= judged_floor(w, opts)
        if (at_minimum) return
        ! the accurate phase of an integrated response (issue 30, cost on
        ! long records): a step of this phase gained less than floor_chi2
        ! and the next Gauss-Newton step promises less than floor_chi2 more,
        ! every parameter within 0.1 sigma of the linearized minimum. The
        ! accurate sensitivities still differ from the derivative of the
        ! integrated predictions (event location, error control) by more
        ! than such a step, so undamped steps went on gaining ~1e-3 each at
        ! one accurate integration with sensitivities apiece (10 s at 500
        ! Hz: five steps, a third of the fit's cost, for 0.03 of chi-square)
        at_minimum = w%integrated .and. rough == ROUGH_OFF .and. it > w%it0 .and. &
                     w%dcost <= noise_floor(w, opts) .and. w%pred_gn <= noise_floor(w, opts)
        if (at_minimum) return
        ! ... and after an undamped step that gained what it promised (the
        ! model smooth at the step's scale), a next step that promises less
        ! than the noise floor: Gauss-Newton's own end, judged against the
        ! noise (5 s at 500 Hz: one accurate run with sensitivities, a
        ! fifth of the fit, for 7e-4 of chi-square)
        at_minimum = w%integrated .and. rough == ROUGH_OFF .and. it > w%it0 .and. &
                     .not. w%poor_step .and. w%pred_gn <= judged_floor(w, opts)
        if (at_minimum) return
        ! the rough model pays while the misfit is well above the data's
        ! noise; once the data are fitted better than their sigmas (chi2
        ! below half the degrees of freedom, as with exact data) what is
        ! left may be the rough model's own error: on to the accurate one
        at_minimum = rough == ROUGH_ALL .and. w%cost < 0.5_dp*max(w%mt - w%n, 1)
    end function at_minimum

    !> The Levenberg-Marquardt trials of one iteration: the damping raised
    !! until a step inside the box lowers the cost (accepted: the trial
    !! arrays w%pt, w%predt, w%at, w%rt hold it, w%cost_t its cost).
    !! evaluated: some trial could be evaluated; w%failed_trial: the last
    !! could not (its message in w%fail_stat).
    subroutine damped_trials(model, lp, opts, w, accepted, evaluated)
        class(residual_model_t), intent(inout) :: model
        type(lsq_problem_t), intent(in) :: lp
        type(fit_options_t), intent(in) :: opts
        type(gn_state_t), intent(inout) :: w
        logical, intent(out) :: accepted, evaluated
        type(status_t) :: trial_stat
        integer :: trial
        accepted = .false.
        evaluated = .false.
        w%failed_trial = .false.
        w%lambda_in = w%lambda
        do trial = 1, opts%max_trials
            w%dx = lm_step(w%d, w%s, w%u, w%vt, w%rr, w%lambda, opts%rcond)
            w%pt = w%p
            w%pt(w%free) = min(max(w%p(w%free) + w%dx, w%lower(w%free)), w%upper(w%free))
            w%dx = w%pt(w%free) - w%p(w%free)
            ! an integrated response: a damped step that promises less than
            ! the noise floor cannot be judged (its cost differs from the
            ! last by the integrator's error): no step lowers the cost above
            ! the noise, a minimum (each trial is one plain run)
            if (trial > 1 .and. w%integrated) then
                if (w%cost - sum((w%rr - matmul(w%aa, w%dx))**2) <= judged_floor(w, opts)) return
            end if
            call clear_status(trial_stat)
            if (model%plain_trials) then
                call weighted_system(model, lp, w%pt, w%free(1:0), w%predt, w%at(:, 1:0), &
                                     w%rt, trial_stat)
            else
                call weighted_system(model, lp, w%pt, w%free, w%predt, w%at, w%rt, trial_stat)
            end if
            if (trial_stat%code == STATUS_OK) then
                evaluated = .true.
                w%failed_trial = .false.
                w%cost_t = sum(w%rt**2)
                if (w%cost_t <= w%cost*(1.0_dp + 8.0_dp*epsilon(1.0_dp)) + tiny(1.0_dp)) then
                    ! the sensitivities at the accepted step
                    if (model%plain_trials) call weighted_system(model, lp, w%pt, w%free, &
                                                                 w%predt, w%at, w%rt, trial_stat)
                    if (trial_stat%code == STATUS_OK) then
                        w%cost_t = sum(w%rt**2)
                        accepted = .true.
                        return
                    end if
                    w%failed_trial = .true.
                    w%fail_stat = trial_stat
                end if
            else
                w%failed_trial = .true.
                w%fail_stat = trial_stat
            end if
            w%lambda = max(10.0_dp*w%lambda, 1.0e-3_dp*w%s(1)**2)
        end do
    end subroutine damped_trials

    !> Move to the accepted trial step and log it as iteration `it`.
    pure subroutine take_step(w, it, res)
        type(gn_state_t), intent(inout) :: w
        integer, intent(in) :: it
        type(fit_result_t), intent(inout) :: res
        w%relstep = maxval(abs(w%dx)/max(abs(w%p(w%free)), abs(w%pt(w%free)), tiny(1.0_dp)))
        w%dcost = w%cost - w%cost_t
        w%pred_step = w%cost - sum((w%rr - matmul(w%aa, w%dx))**2)
        w%poor_step = w%lambda > 0.0_dp .or. w%dcost < 0.25_dp*w%pred_step
        w%p = w%pt
        w%pred = w%predt
        w%a = w%at
        w%rr = w%rt
        res%nlog = it
        res%log_cost(it) = w%cost_t
        res%log_lambda(it) = w%lambda
        res%log_step(it) = w%relstep
        res%log_params(:, it) = w%p(w%free)
    end subroutine take_step

    !> Count the damped steps that get nowhere (w%nstuck: three is a stall)
    !! after the step of iteration `it`, which becomes the current cost.
    pure subroutine count_stuck_steps(w, it, res, opts)
        type(gn_state_t), intent(inout) :: w
        integer, intent(in) :: it
        type(fit_result_t), intent(in) :: res
        type(fit_options_t), intent(in) :: opts
        ! a damped step that moves nothing though the damping had to be
        ! raised again (not on its way down): three in a row is a stall
        if (w%lambda > w%lambda_in .and. &
            (w%relstep < opts%tol_step .or. w%dcost <= opts%tol_cost*w%cost_t)) then
            w%nstuck = w%nstuck + 1
        else
            w%nstuck = 0
        end if
        w%cost = w%cost_t
        if (w%poor_step .and. w%dcost <= noise_floor(w, opts)) then
            w%nfloor = w%nfloor + 1
        else
            w%nfloor = 0
        end if
        ! ... and so is a damped crawl: ten damped steps that lower the
        ! chi-square by less than 0.01 together (a curved valley along
        ! collinear columns; no statistical meaning is left to gain)
        if (it > CRAWL_STEPS) then
            if (all(res%log_lambda(it - CRAWL_STEPS + 1:it) > 0.0_dp) .and. &
                res%log_cost(it - CRAWL_STEPS) - w%cost_t < CRAWL_DROP) w%nstuck = 3
        end if
    end subroutine count_stuck_steps

    !> A parameter that ran away is held there; the others go on.
    pure subroutine hold_runaways(w, opts)
        type(gn_state_t), intent(inout) :: w
        type(fit_options_t), intent(in) :: opts
        integer :: i, f
        do i = 1, w%n
            if (w%held(i)) cycle
            f = w%free(i)
            if (ran_away(w%p(f), w%p0(f), w%lower(f), opts)) then
                w%held(i) = .true.
                w%lambda = 0.0_dp
                w%nstuck = 0
                w%stall_pending = .false.
            end if
        end do
    end subroutine hold_runaways

    !> The end of a rough phase: predictions and Jacobian at the user's
    !! tolerance at the final point (one sensitivity run), and the
    !! Gauss-Newton decrease they predict. go_on: that still promises more
    !! than the noise floor and iterations are left. After the phase on
    !! the rough model the floor is scaled by the misfit, chi-square per
    !! degree of freedom (about 1 with noisy data: the same floor): with
    !! (nearly) exact data the rough model's own noise floor is far above
    !! the accurate model's, and the fit goes on to the accurate minimum.
    subroutine confirm_at_final_point(model, lp, opts, w, iterations, go_on, st)
        class(residual_model_t), intent(inout) :: model
        type(lsq_problem_t), intent(in) :: lp
        integer, intent(in) :: iterations
        type(fit_options_t), intent(in) :: opts
        type(gn_state_t), intent(inout) :: w
        logical, intent(out) :: go_on
        type(status_t), intent(inout) :: st
        type(status_t) :: est
        model%rough = ROUGH_OFF
        go_on = .false.
        call weighted_system(model, lp, w%p, w%free, w%pred, w%a, w%rr, est)
        if (est%code /= STATUS_OK) then
            est%message = trim(est%message)//' (the accurate Jacobian at the estimates)'
            st = est
            return
        end if
        w%cost = sum(w%rr**2)
        if (all(w%held) .or. iterations >= opts%max_iter) return
        call projected_svd(w, opts, est)
        if (est%code /= STATUS_OK) then
            st = est
            return
        end if
        w%pred_gn = predicted_decrease(w%s, w%u, w%rr, opts%rcond)
        if (w%level == ROUGH_ALL) then
            go_on = w%pred_gn > noise_floor(w, opts)*min(1.0_dp, w%cost/max(w%mt - w%n, 1)) .and. &
                    w%cost > 1.0e-18_dp*w%mt
        else
            go_on = w%pred_gn > noise_floor(w, opts)
        end if
    end subroutine confirm_at_final_point

    !> Iterate on from the final point (one level less rough), the
    !! iteration's state as after an undamped step.
    pure subroutine restart_phase(w, res)
        type(gn_state_t), intent(inout) :: w
        type(fit_result_t), intent(inout) :: res
        w%it0 = res%iterations + 1
        res%converged = .false.
        w%stalled = .false.
        w%stall_pending = .false.
        w%failed_trial = .false.
        w%poor_step = .false.
        w%nfloor = 0
        w%nstuck = 0
        w%lambda = 0.0_dp
    end subroutine restart_phase

    !> The fit's result at the final iterate: the log cut to its length,
    !! residuals, chi-square, and the covariance, sigmas and flags from the
    !! accurate Jacobian (a held parameter's column left out: the others'
    !! covariance is conditional on it, and it gets an infinite sigma).
    subroutine store_result(w, opts, res, stat)
        type(gn_state_t), intent(inout) :: w
        type(fit_options_t), intent(in) :: opts
        type(fit_result_t), intent(inout) :: res
        type(status_t), intent(inout) :: stat
        logical :: undetermined(w%n)
        type(status_t) :: cov_stat
        integer :: i, m, n
        m = w%m
        n = w%n
        res%log_cost = res%log_cost(0:res%nlog)
        res%log_lambda = res%log_lambda(0:res%nlog)
        res%log_step = res%log_step(0:res%nlog)
        res%log_params = res%log_params(:, 0:res%nlog)
        res%params = w%p
        res%estimates = w%p(w%free)
        res%predictions = w%pred
        res%normalized = w%rr(1:m)
        res%chi2 = sum(w%rr(1:m)**2)
        res%chi2_prior = sum(w%rr(m + 1:)**2)
        res%dof = w%mt - n
        allocate (res%cov(n, n), res%corr(n, n), res%sigmas(n), res%flags(n))
        w%aa = w%a
        do i = 1, n
            if (w%held(i)) w%aa(:, i) = 0.0_dp
        end do
        call covariance(w%aa, opts, res%cov, res%sigmas, res%corr, res%cond, res%rank, &
                        undetermined, cov_stat)
        if (cov_stat%code /= STATUS_OK) then
            if (stat%code == STATUS_OK) stat = cov_stat
            return
        end if
        call set_flags(res, w%p0, w%lower, w%upper, undetermined, opts)
    end subroutine store_result

    !> How the fit ended (res%stop) and, unless converged, why (res%note);
    !! still moving at the iteration limit is ERR_NO_CONVERGENCE.
    subroutine describe_ending(w, opts, res, stat)
        type(gn_state_t), intent(in) :: w
        type(fit_options_t), intent(in) :: opts
        type(fit_result_t), intent(inout) :: res
        type(status_t), intent(inout) :: stat
        if (any(w%held)) then
            res%stop = STOP_RUNAWAY
            if (all(w%held)) then
                res%note = 'no parameter left to fit'
            else if (res%converged) then
                res%note = 'the others fitted'
            else if (w%stalled) then
                res%note = 'the others stalled'
            else
                res%note = 'the others still moving at the iteration limit'
            end if
            res%note = flag_list(res, w%p0, w%lower, w%upper, opts, w%held)// &
                       '; held where found after '//fmt_int(res%iterations)// &
                       ' iterations, '//res%note
            res%converged = .false.
        else if (w%stalled) then
            res%converged = .false.
            res%stop = STOP_STALLED
            res%note = 'Gauss-Newton stalled after '//fmt_int(res%iterations)// &
                       ' iterations (last relative step '//fmt_real(w%relstep)// &
                       ', cost change '//fmt_real(w%dcost)//', damping '// &
                       fmt_real(w%lambda)//'): '
            if (w%failed_trial) then
                res%note = res%note//'the model could not be solved at the smallest trial '// &
                           'step ('//trim(w%fail_stat%message)//'); '
            end if
            res%note = res%note//flag_list(res, w%p0, w%lower, w%upper, opts, w%held)
        else if (res%converged) then
            res%stop = STOP_CONVERGED
        else
            res%stop = STOP_MAX_ITER
            call set_status(stat, ERR_NO_CONVERGENCE, 'fit', 'Gauss-Newton did not converge '// &
                            'in '//fmt_int(res%iterations)//' iterations (last relative step '// &
                            fmt_real(w%relstep)//', cost change '//fmt_real(w%dcost)// &
                            ', chi-square '//fmt_real(res%chi2)//')')
            res%note = trim(stat%message)
        end if
    end subroutine describe_ending

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
    subroutine fit_at(model, lp, params, free, opts, res, stat)
        class(residual_model_t), intent(inout) :: model
        type(lsq_problem_t), intent(in) :: lp
        real(dp), intent(in) :: params(:)
        integer, intent(in) :: free(:)
        type(fit_options_t), intent(in) :: opts
        type(fit_result_t), intent(out) :: res
        type(status_t), intent(inout) :: stat
        integer :: m, n, mt
        real(dp), allocatable :: pred(:), a(:, :), rr(:)
        logical, allocatable :: undetermined(:)
        call check_problem(lp, params, free, stat)
        if (stat%code /= STATUS_OK) return
        m = size(lp%y)
        n = size(free)
        mt = m + size(lp%prior%index)
        allocate (pred(m), a(mt, n), rr(mt))
        call weighted_system(model, lp, params, free, pred, a, rr, stat)
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
        res%log_cost = [sum(rr**2)]
        res%log_lambda = [0.0_dp]
        res%log_step = [0.0_dp]
        res%log_params = reshape(params(free), [n, 1])
        allocate (res%cov(n, n), res%corr(n, n), res%sigmas(n), res%flags(n), undetermined(n))
        call covariance(a, opts, res%cov, res%sigmas, res%corr, res%cond, res%rank, &
                        undetermined, stat)
        if (stat%code /= STATUS_OK) return
        call set_flags(res, params, lp%lower, lp%upper, undetermined, opts)
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
            if (res%sigmas(i) > WEAK_RELATIVE_SIGMA*abs(x)) res%flags(i) = FLAG_WEAK
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
    subroutine score_test(model, lp, params, free, block, opts, res, stat)
        class(residual_model_t), intent(inout) :: model
        type(lsq_problem_t), intent(in) :: lp
        real(dp), intent(in) :: params(:)
        integer, intent(in) :: free(:), block(:)
        type(fit_options_t), intent(in) :: opts
        type(score_result_t), intent(out) :: res
        type(status_t), intent(inout) :: stat
        integer :: m, mt, nf, nb, rf, k, j, worst
        integer, allocatable :: cols(:), side(:)
        real(dp), allocatable :: pred(:), a(:, :), rr(:), ab(:, :), d(:), s(:), u(:, :)
        real(dp), allocatable :: vt(:, :), cov(:, :), sig(:), corr(:, :), delta(:)
        real(dp) :: viol, worst_viol
        logical, allocatable :: und(:)

        m = size(lp%y)
        mt = m + size(lp%prior%index)
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
        call weighted_system(model, lp, params, cols, pred, a, rr, stat)
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
            if (params(block(j)) <= lp%lower(block(j))) side(j) = 1
            if (params(block(j)) >= lp%upper(block(j))) side(j) = -1
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
                if (params(block(j)) + delta(j) > lp%upper(block(j)) + 3.0_dp*sig(j) .or. &
                    params(block(j)) + delta(j) < lp%lower(block(j)) - 3.0_dp*sig(j)) &
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
            allocate (dl(nb), source=0.0_dp)
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
    !! whatever the nominal model). With `last_resort` the continuation
    !! runs only when neither earlier start converged. Starts after one whose chi-square is
    !! consistent with the noise (below dof + 3 sqrt(2 dof)) are skipped: no
    !! other minimum can be significantly better. `info%note` says what each start gave. When
    !! none converges, `res` is the lowest-cost attempt (flagged) and the
    !! status is ERR_NO_CONVERGENCE with the notes; a model that cannot be
    !! evaluated at base%params is an error as usual.
    subroutine refit_effect(model, lp, base, block, score, nominal, opts, res, info, stat, &
                            ncont, use, enough, last_resort)
        class(residual_model_t), intent(inout) :: model
        type(lsq_problem_t), intent(in) :: lp
        real(dp), intent(in) :: nominal(:)
        type(fit_result_t), intent(in) :: base
        integer, intent(in) :: block(:)
        type(score_result_t), intent(in) :: score
        type(fit_options_t), intent(in) :: opts
        type(fit_result_t), intent(out) :: res
        type(refit_info_t), intent(out) :: info
        type(status_t), intent(inout) :: stat
        integer, intent(in), optional :: ncont  !< continuation steps (default 4)
        logical, intent(in), optional :: use(3) !< which starts to try (default all)
        !> stop at a converged start with half the predicted drop (default no)
        logical, intent(in), optional :: enough
        !> the continuation only when no earlier start converged (default no)
        logical, intent(in), optional :: last_resort
        integer :: nb, half, nsteps, kk
        logical :: try(3), same
        integer, allocatable :: all_free(:)
        real(dp), allocatable :: target(:), start(:), shift(:), p(:)
        real(dp) :: t
        type(fit_result_t) :: trial
        type(status_t) :: st
        type(refit_state_t) :: rs
        character(len=:), allocatable :: why

        nb = size(block)
        nsteps = 4
        if (present(ncont)) nsteps = max(ncont, 1)
        try = .true.
        if (present(use)) try = use
        rs%base_cost = base%chi2 + base%chi2_prior
        if (present(enough)) then
            if (enough .and. score%drop > 0.0_dp) rs%half_drop = 0.5_dp*score%drop
        end if
        all_free = [base%free, block]
        info%note = ''
        if (base%dof - nb > 0) rs%noise = real(base%dof - nb, dp) + &
                                          3.0_dp*sqrt(2.0_dp*real(base%dof - nb, dp))
        call first_order_target(score, lp%nulls(block), size(base%free), target, shift)

        ! 1. the first-order start, halved while the model cannot be solved there
        t = 1.0_dp
        if (try(1)) then
            do half = 0, 4
                start = base%params
                start(base%free) = base%params(base%free) + t*shift
                start(block) = lp%nulls(block) + t*(target - lp%nulls(block))
                call into_box(start, all_free, lp%lower, lp%upper, base%params)
                call clear_status(st)
                call fit_least_squares(model, lp, start, all_free, opts, trial, st)
                if (allocated(trial%params) .or. st%code <= 0 .or. half == 4) exit
                t = 0.5_dp*t
            end do
            call consider_refit(START_SCORE, trial, st, rs, res, info, stat, shortened_to=t)
            if (stat%code /= STATUS_OK) return
        end if

        ! 2. the nominal model with the effect at its null value
        if (try(2) .and. .not. refit_done(rs)) then
            start = base%params
            start(base%free) = nominal(base%free)
            start(block) = lp%nulls(block)
            call into_box(start, all_free, lp%lower, lp%upper, base%params)
            same = try(1) .and. all(start == base%params) .and. all(shift == 0.0_dp) .and. &
                   all(target == lp%nulls(block))
            if (.not. same) then
                call clear_status(st)
                call fit_least_squares(model, lp, start, all_free, opts, trial, st)
                call consider_refit(START_NOMINAL, trial, st, rs, res, info, stat)
                if (stat%code /= STATUS_OK) return
            end if
        end if

        ! 3. continuation in the effect's strength from its null value
        if (present(last_resort)) then
            if (last_resort .and. rs%have_best) try(3) = .false.
        end if
        if (try(3) .and. .not. refit_done(rs) .and. any(target /= lp%nulls(block))) then
            call continue_in_strength(model, lp, base, block, target, all_free, opts, nsteps, &
                                      p, kk, why)
            if (kk > 0) then
                call clear_status(st)
                call fit_least_squares(model, lp, p, all_free, opts, trial, st)
                call consider_refit(START_CONTINUATION, trial, st, rs, res, info, stat)
                if (stat%code /= STATUS_OK) return
            else
                call add_refit_note(info, trim(REFIT_LABEL(3))// &
                                    ': the first step could not be fitted ('//why//')')
            end if
        end if

        if (.not. rs%have_best) then
            if (rs%have_fallback) res = rs%fallback
            call set_status(stat, ERR_NO_CONVERGENCE, 'refit', 'no start converged: '// &
                            info%note)
        end if
    end subroutine refit_effect

    !> The first-order target of an effect's block (null values plus the
    !! score test's estimate of its active parameters) and the free
    !! parameters' shift that goes with it (score%free_step; 0 without one).
    pure subroutine first_order_target(score, null_block, nf, target, shift)
        type(score_result_t), intent(in) :: score
        real(dp), intent(in) :: null_block(:)
        integer, intent(in) :: nf
        real(dp), allocatable, intent(out) :: target(:), shift(:)
        integer :: j
        target = null_block
        allocate (shift(nf), source=0.0_dp)
        if (.not. allocated(score%estimate)) return
        if (size(score%estimate) == size(null_block)) then
            do j = 1, size(null_block)
                if (score%active(j)) target(j) = null_block(j) + score%estimate(j)
            end do
        end if
        if (allocated(score%free_step)) then
            if (size(score%free_step) == nf) shift = score%free_step
        end if
    end subroutine first_order_target

    !> Refit start 3: the block stepped from its null value to `target` in
    !! nsteps steps, base%free fitted at each; p: the last point fitted
    !! (kk steps done; 0: the first failed, `why` says how).
    subroutine continue_in_strength(model, lp, base, block, target, all_free, opts, nsteps, p, &
                                    kk, why)
        class(residual_model_t), intent(inout) :: model
        type(lsq_problem_t), intent(in) :: lp
        real(dp), intent(in) :: target(:)
        type(fit_result_t), intent(in) :: base
        integer, intent(in) :: block(:), all_free(:), nsteps
        type(fit_options_t), intent(in) :: opts
        real(dp), allocatable, intent(out) :: p(:)
        integer, intent(out) :: kk
        character(len=:), allocatable, intent(out) :: why
        real(dp), allocatable :: start(:)
        type(fit_result_t) :: fixed
        type(status_t) :: st
        integer :: k
        p = base%params
        kk = 0
        why = ''
        do k = 1, nsteps
            start = p
            start(block) = lp%nulls(block) + real(k, dp)/real(nsteps, dp)* &
                           (target - lp%nulls(block))
            call into_box(start, all_free, lp%lower, lp%upper, base%params)
            call clear_status(st)
            call fit_least_squares(model, lp, start, base%free, opts, fixed, st)
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
    end subroutine continue_in_strength

    !> Keep the refit `tr` (start `which`) if it converged and beats the best
    !! so far, else as the fallback if it is the lowest-cost attempt; note
    !! what it gave. Bad input (st1%code < 0) is returned in stat.
    subroutine consider_refit(which, tr, st1, rs, res, info, stat, shortened_to)
        integer, intent(in) :: which
        type(fit_result_t), intent(in) :: tr
        type(status_t), intent(in) :: st1
        type(refit_state_t), intent(inout) :: rs
        type(fit_result_t), intent(inout) :: res
        type(refit_info_t), intent(inout) :: info
        type(status_t), intent(inout) :: stat
        real(dp), intent(in), optional :: shortened_to !< step factor of the start
        character(len=:), allocatable :: what
        real(dp) :: cost
        info%tried = info%tried + 1
        what = trim(REFIT_LABEL(which))
        if (present(shortened_to)) then
            if (shortened_to < 1.0_dp) what = what//' (shortened to '//fmt_real(shortened_to)//')'
        end if
        if (st1%code < 0) then
            ! bad input is bad input, whatever the start
            stat = st1
            return
        end if
        if (.not. allocated(tr%params)) then
            call add_refit_note(info, what//': '//trim(st1%message))
            return
        end if
        cost = tr%chi2 + tr%chi2_prior
        if (st1%code == STATUS_OK .and. tr%stop == STOP_CONVERGED) then
            call add_refit_note(info, what//': converged, chi-square '//fmt_real(tr%chi2))
            ! a later start must do better than the same minimum reached
            ! again (ties go to the earlier start)
            if (.not. rs%have_best .or. &
                cost < rs%best_cost - 1.0e-6_dp*rs%best_cost - 1.0e-9_dp) then
                res = tr
                rs%best_cost = cost
                rs%have_best = .true.
                info%start = which
            end if
        else
            if (allocated(tr%note)) then
                call add_refit_note(info, what//': '//tr%note)
            else
                call add_refit_note(info, what//': '//trim(st1%message))
            end if
            if (.not. rs%have_best .and. .not. rs%have_fallback) then
                rs%fallback = tr
                rs%have_fallback = .true.
            else if (.not. rs%have_best) then
                if (cost < rs%fallback%chi2 + rs%fallback%chi2_prior) rs%fallback = tr
            end if
        end if
    end subroutine consider_refit

    !> No further refit start is needed: the best so far is consistent with
    !! the noise, or (first_enough) gained half the predicted drop.
    pure logical function refit_done(rs)
        type(refit_state_t), intent(in) :: rs
        refit_done = rs%have_best .and. (rs%best_cost <= rs%noise .or. &
                                         rs%base_cost - rs%best_cost >= rs%half_drop)
    end function refit_done

    pure subroutine add_refit_note(info, text)
        type(refit_info_t), intent(inout) :: info
        character(len=*), intent(in) :: text
        if (len(info%note) > 0) info%note = info%note//'; '
        info%note = info%note//text
    end subroutine add_refit_note

    !> Clip the parameters `free` of q into the bounds; a parameter bounded
    !! below by 0 (a stiffness, never 0 in the solver) keeps half its base value.
    pure subroutine into_box(q, free, lower, upper, base_params)
        real(dp), intent(inout) :: q(:)
        integer, intent(in) :: free(:)
        real(dp), intent(in) :: lower(:), upper(:), base_params(:)
        integer :: i, ip
        do i = 1, size(free)
            ip = free(i)
            q(ip) = min(max(q(ip), lower(ip)), upper(ip))
            if (lower(ip) == 0.0_dp .and. q(ip) <= 0.0_dp .and. base_params(ip) > 0.0_dp) &
                q(ip) = 0.5_dp*base_params(ip)
        end do
    end subroutine into_box

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
    subroutine diagnose(model, lp, base, cands, fopts, dopts, diag, stat, probe, probe_sigma, &
                        nominal)
        class(residual_model_t), intent(inout) :: model
        type(lsq_problem_t), intent(in) :: lp
        type(fit_result_t), intent(in) :: base
        type(candidate_t), intent(in) :: cands(:)
        type(fit_options_t), intent(in) :: fopts
        type(diagnose_options_t), intent(in) :: dopts
        type(diagnosis_t), intent(out) :: diag
        type(status_t), intent(inout) :: stat
        class(residual_model_t), intent(inout), optional :: probe
        real(dp), intent(in), optional :: probe_sigma(:)
        real(dp), intent(in), optional :: nominal(:) !< starting values of the user's
        !! model, a start of the refits (default: base%params)
        integer :: nc, c, q, nrefit
        integer, allocatable :: order(:)
        real(dp), allocatable :: start(:)
        type(status_t) :: st

        start = base%params
        if (present(nominal)) start = nominal
        nc = size(cands)
        allocate (diag%cand(nc), diag%cosine(nc, nc))
        diag%cosine = 0.0_dp
        call score_candidates(model, lp, base, cands, fopts, diag, stat)
        if (stat%code /= STATUS_OK) return
        diag%alpha_each = dopts%alpha/real(max(diag%ntested, 1), dp)
        call direction_cosines(diag)
        order = sort_desc(first_pass_key(diag))
        ! confirm the leading candidates by refits
        nrefit = 0
        do q = 1, nc
            c = order(q)
            if (nrefit >= dopts%nrefit) exit
            if (.not. worth_refit(diag%cand(c)%state, diag%cand(c)%score, dopts)) cycle
            nrefit = nrefit + 1
            associate (cr => diag%cand(c))
                call clear_status(st)
                call refit_effect(model, lp, base, cands(c)%params, cr%score, start, fopts, &
                                  cr%refit, cr%info, st, use=dopts%starts, &
                                  enough=dopts%first_enough, &
                                  last_resort=dopts%continue_if_none)
                if (st%code < 0) then
                    stat = st
                    return
                end if
                call judge_refit(cr, st%code == STATUS_OK, base, cands(c)%params, lp, &
                                 diag%alpha_each)
            end associate
        end do
        call rank_candidates(diag, cands)
        if (diag%verdict == 0) return
        call mark_rivals(diag, cands, dopts)
        if (.not. present(probe) .or. .not. present(probe_sigma)) return
        if (.not. any(diag%cand%rival)) return
        call separating_rows(probe, probe_sigma, diag, stat)
    end subroutine diagnose

    !> Diagnosis step 1: the state of every candidate, and the score test of
    !! those whose parameters are all at their null values and not free.
    subroutine score_candidates(model, lp, base, cands, fopts, diag, stat)
        class(residual_model_t), intent(inout) :: model
        type(lsq_problem_t), intent(in) :: lp
        type(fit_result_t), intent(in) :: base
        type(candidate_t), intent(in) :: cands(:)
        type(fit_options_t), intent(in) :: fopts
        type(diagnosis_t), intent(inout) :: diag
        type(status_t), intent(inout) :: stat
        integer :: c, k
        do c = 1, size(cands)
            associate (cr => diag%cand(c))
                if (size(cands(c)%params) == 0) then
                    cr%state = CAND_NO_PARAMS
                else if (any([(any(base%free == cands(c)%params(k)), &
                               k=1, size(cands(c)%params))])) then
                    cr%state = CAND_FREE
                else if (any(base%params(cands(c)%params) /= lp%nulls(cands(c)%params))) then
                    cr%state = CAND_ACTIVE
                else
                    cr%state = CAND_TESTED
                    call score_test(model, lp, base%params, base%free, cands(c)%params, fopts, &
                                    cr%score, stat)
                    if (stat%code /= STATUS_OK) then
                        stat%message = trim(stat%message)//' (score test of '// &
                                       cands(c)%name//')'
                        return
                    end if
                    diag%ntested = diag%ntested + 1
                end if
            end associate
        end do
    end subroutine score_candidates

    !> Diagnosis step 2: cosines between the tested candidates' directions.
    pure subroutine direction_cosines(diag)
        type(diagnosis_t), intent(inout) :: diag
        integer :: c, k
        do c = 1, size(diag%cand)
            do k = 1, size(diag%cand)
                if (diag%cand(c)%state == CAND_TESTED .and. &
                    diag%cand(k)%state == CAND_TESTED) diag%cosine(c, k) = &
                    dot_product(diag%cand(c)%score%direction, diag%cand(k)%score%direction)
            end do
        end do
    end subroutine direction_cosines

    !> Diagnosis step 3, the order of the refits: by predicted drop, physical
    !! and identifiable candidates first, untested ones last.
    pure function first_pass_key(diag) result(key)
        type(diagnosis_t), intent(in) :: diag
        real(dp) :: key(size(diag%cand))
        integer :: c
        do c = 1, size(diag%cand)
            key(c) = -huge(1.0_dp)
            if (diag%cand(c)%state /= CAND_TESTED) cycle
            key(c) = diag%cand(c)%score%drop
            if (.not. (diag%cand(c)%score%physical .and. diag%cand(c)%score%identifiable)) &
                key(c) = key(c) - 1.0e30_dp
        end do
    end function first_pass_key

    !> Is a candidate worth confirming by a refit: tested, physical,
    !! identifiable, a positive predicted drop (and, when asked, significant).
    pure logical function worth_refit(state, score, dopts)
        integer, intent(in) :: state
        type(score_result_t), intent(in) :: score
        type(diagnose_options_t), intent(in) :: dopts
        worth_refit = .false.
        if (state /= CAND_TESTED) return
        if (.not. (score%physical .and. score%identifiable)) return
        if (score%drop <= 0.0_dp) return
        if (dopts%refit_significant_only .and. .not. score%p_value < dopts%alpha) return
        worth_refit = .true.
    end function worth_refit

    !> Diagnosis step 4: the likelihood-ratio test of a refit (`ok`: it
    !! converged) and whether it is an acceptable explanation.
    pure subroutine judge_refit(cr, ok, base, block, lp, alpha_each)
        type(candidate_report_t), intent(inout) :: cr
        logical, intent(in) :: ok
        type(fit_result_t), intent(in) :: base
        integer, intent(in) :: block(:)
        type(lsq_problem_t), intent(in) :: lp
        real(dp), intent(in) :: alpha_each
        integer :: k
        cr%refit_done = .true.
        cr%refit_ok = ok
        if (.not. ok) then
            cr%lr_drop = not_a_number()
            cr%lr_p = not_a_number()
            return
        end if
        cr%lr_drop = (base%chi2 + base%chi2_prior) - (cr%refit%chi2 + cr%refit%chi2_prior)
        cr%lr_p = chi2_sf(max(cr%lr_drop, 0.0_dp), size(block))
        if (size(block) == 1 .and. any(cr%score%active .and. &
            (base%params(block) <= lp%lower(block) .or. base%params(block) >= lp%upper(block)))) &
            cr%lr_p = 0.5_dp*cr%lr_p
        cr%significant = cr%lr_p < alpha_each
        k = size(base%free)
        ! a refit that returns the effect to its null value (a bound) or
        ! cannot determine it is not an explanation; a bound away from
        ! the null (axial_coupling = 1, the exact form) is
        cr%acceptable = cr%significant .and. &
                        all(cr%refit%flags(k + 1:) /= FLAG_UNDETERMINED) .and. &
                        all(cr%refit%flags(k + 1:) /= FLAG_RUNAWAY) .and. &
                        any(cr%refit%params(block) /= lp%nulls(block))
    end subroutine judge_refit

    !> Diagnosis step 5: final ranking in tiers: acceptable refits, other
    !! refits, physical score tests, the rest; within a tier by the
    !! Akaike-style gain drop - 2 dof (refits: actual drop, otherwise the
    !! predicted one). The verdict is the best acceptable candidate.
    pure subroutine rank_candidates(diag, cands)
        type(diagnosis_t), intent(inout) :: diag
        type(candidate_t), intent(in) :: cands(:)
        real(dp) :: key(size(diag%cand))
        integer :: tier(size(diag%cand))
        integer :: c, q
        do c = 1, size(diag%cand)
            key(c) = -huge(1.0_dp)
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
        diag%verdict = 0
        do q = 1, size(diag%cand)
            c = diag%ranking(q)
            if (diag%cand(c)%acceptable) then
                diag%verdict = c
                exit
            end if
        end do
    end subroutine rank_candidates

    !> Diagnosis step 6: rivals explain the residuals about as well as the
    !! verdict (gains within ambiguity_delta, or twice that when collinear).
    pure subroutine mark_rivals(diag, cands, dopts)
        type(diagnosis_t), intent(inout) :: diag
        type(candidate_t), intent(in) :: cands(:)
        type(diagnose_options_t), intent(in) :: dopts
        integer :: c, best
        best = diag%verdict
        do c = 1, size(diag%cand)
            if (c == best .or. .not. diag%cand(c)%acceptable) cycle
            if ((diag%cand(best)%lr_drop - 2.0_dp*size(cands(best)%params)) - &
                (diag%cand(c)%lr_drop - 2.0_dp*size(cands(c)%params)) < &
                dopts%ambiguity_delta .or. (abs(diag%cosine(best, c)) > dopts%collinear &
                .and. (diag%cand(best)%lr_drop - 2.0_dp*size(cands(best)%params)) - &
                (diag%cand(c)%lr_drop - 2.0_dp*size(cands(c)%params)) < &
                2.0_dp*dopts%ambiguity_delta)) diag%cand(c)%rival = .true.
        end do
    end subroutine mark_rivals

    !> Diagnosis step 7: for each rival, the probe row whose predictions
    !! differ most from the verdict's (in units of probe_sigma).
    subroutine separating_rows(probe, probe_sigma, diag, stat)
        class(residual_model_t), intent(inout) :: probe
        real(dp), intent(in) :: probe_sigma(:)
        type(diagnosis_t), intent(inout) :: diag
        type(status_t), intent(inout) :: stat
        real(dp) :: pa(size(probe_sigma)), pb(size(probe_sigma)), jdummy(size(probe_sigma), 0)
        integer :: c, row
        call probe%evaluate(diag%cand(diag%verdict)%refit%params, [integer ::], pa, jdummy, stat)
        if (stat%code /= STATUS_OK) return
        do c = 1, size(diag%cand)
            if (.not. diag%cand(c)%rival) cycle
            call probe%evaluate(diag%cand(c)%refit%params, [integer ::], pb, jdummy, stat)
            if (stat%code /= STATUS_OK) return
            row = maxloc(abs(pa - pb)/probe_sigma, 1)
            diag%cand(c)%separating_row = row
            diag%cand(c)%separation = abs(pa(row) - pb(row))/probe_sigma(row)
        end do
    end subroutine separating_rows

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
        integer :: n, i, j, nsign, n1, n2, runs
        integer, allocatable :: idx(:), signs(:)
        logical, allocatable :: seen(:)
        real(dp) :: mean, var, z, xbar, sxx, sxy, nn

        out = not_a_number()
        n = size(normalized)
        allocate (signs(n), seen(n))
        seen = .false.
        nsign = 0
        do i = 1, n
            if (seen(i)) cycle
            ! rows of this group in their original order, then a stable sort by
            ! ascending level (descending -level)
            idx = pack([(j, j=i, n)], group(i:n) == group(i))
            seen(idx) = .true.
            idx = idx(sort_desc(-level(idx)))
            do j = 1, size(idx)
                if (normalized(idx(j)) /= 0.0_dp) then
                    nsign = nsign + 1
                    signs(nsign) = merge(1, 0, normalized(idx(j)) > 0.0_dp)
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
