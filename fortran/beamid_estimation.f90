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
    public :: diagnosis_t
    public :: fit_least_squares, score_test, diagnose, chi2_sf, residual_structure

    !> Per-parameter flags of a fit (worst first).
    integer, parameter, public :: FLAG_OK = 0           !< determined
    integer, parameter, public :: FLAG_UNDETERMINED = 1 !< infinite or > 100 % sigma
    integer, parameter, public :: FLAG_RUNAWAY = 2      !< moved by more than runaway_factor
    integer, parameter, public :: FLAG_CORRELATED = 3   !< |correlation| above corr_limit
    integer, parameter, public :: FLAG_AT_BOUND = 4     !< estimate sits on a bound
    !! priority when several apply: undetermined, runaway, at bound, correlated

    !> Candidate states in a diagnosis.
    integer, parameter, public :: CAND_TESTED = 0   !< score test done
    integer, parameter, public :: CAND_FREE = 1     !< a parameter of it is already free
    integer, parameter, public :: CAND_ACTIVE = 2   !< a parameter is not at its null value
    integer, parameter, public :: CAND_NO_PARAMS = 3 !< the model has none of its parameters

    !> An experiment family: predictions and sensitivities of its data rows.
    type, abstract :: residual_model_t
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
    !! Each entry adds the pseudo-measurement (mean - p) / sigma.
    type :: prior_t
        integer, allocatable :: index(:)
        real(dp), allocatable :: mean(:), sigma(:)
    end type prior_t

    type :: fit_options_t
        integer :: max_iter = 50          !< Gauss-Newton iterations
        integer :: max_trials = 20        !< LM damping increases per iteration
        real(dp) :: tol_step = 1.0e-9_dp  !< converged when max |dp_i| / |p_i| is below
        real(dp) :: tol_cost = 1.0e-10_dp !< ... or the relative cost change is below
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
    end type diagnose_options_t

    type :: candidate_report_t
        integer :: state = CAND_TESTED
        type(score_result_t) :: score
        logical :: refit_done = .false.
        logical :: refit_ok = .false.
        type(fit_result_t) :: refit
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
        do i = 1, size(prior%index)
            r(m + i) = (prior%mean(i) - params(prior%index(i)))/prior%sigma(i)
            do j = 1, size(cols)
                if (cols(j) == prior%index(i)) a(m + i, j) = 1.0_dp/prior%sigma(i)
            end do
        end do
    end subroutine weighted_system

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
    !! the cost is retried with Levenberg-Marquardt damping. Converged when
    !! the relative step or the relative cost change of an undamped step falls
    !! below the tolerances. On ERR_NO_CONVERGENCE `res` still holds the last
    !! iterate and its log.
    subroutine fit_least_squares(model, y, sigma, params0, free, lower, upper, prior, opts, &
                                 res, stat)
        class(residual_model_t), intent(inout) :: model
        real(dp), intent(in) :: y(:), sigma(:), params0(:), lower(:), upper(:)
        integer, intent(in) :: free(:)
        type(prior_t), intent(in) :: prior
        type(fit_options_t), intent(in) :: opts
        type(fit_result_t), intent(out) :: res
        type(status_t), intent(inout) :: stat
        integer :: m, n, mt, r, it, trial, i
        real(dp), allocatable :: p(:), pt(:), pred(:), predt(:), a(:, :), at(:, :), rr(:), rt(:)
        real(dp), allocatable :: aa(:, :), g(:)
        real(dp), allocatable :: d(:), s(:), u(:, :), vt(:, :), dx(:)
        real(dp) :: cost, cost_t, lambda, relstep, dcost, lam_floor
        logical :: accepted, evaluated
        type(status_t) :: trial_stat
        logical, allocatable :: undetermined(:)

        call check_problem(y, sigma, params0, free, lower, upper, prior, stat)
        if (stat%code /= STATUS_OK) return
        m = size(y)
        n = size(free)
        mt = m + size(prior%index)
        r = min(mt, n)
        allocate (pred(m), predt(m), a(mt, n), at(mt, n), rr(mt), rt(mt))
        allocate (d(n), s(r), u(mt, r), vt(r, n), dx(n))
        allocate (res%log_cost(0:opts%max_iter), res%log_lambda(0:opts%max_iter), &
                  res%log_step(0:opts%max_iter), res%log_params(n, 0:opts%max_iter))
        res%free = free
        p = params0
        call weighted_system(model, y, sigma, p, free, prior, pred, a, rr, stat)
        if (stat%code /= STATUS_OK) then
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
        relstep = 0.0_dp
        dcost = 0.0_dp
        do it = 1, opts%max_iter
            ! projected Gauss-Newton: a parameter on a bound whose descent
            ! direction (a^T r) points out of the box is held for this step
            aa = a
            g = matmul(rr, a)
            do i = 1, n
                if ((p(free(i)) <= lower(free(i)) .and. g(i) < 0.0_dp) .or. &
                    (p(free(i)) >= upper(free(i)) .and. g(i) > 0.0_dp)) aa(:, i) = 0.0_dp
            end do
            call scaled_svd(aa, d, s, u, vt, stat)
            if (stat%code /= STATUS_OK) return
            lam_floor = 1.0e-6_dp*s(1)**2
            ! first-order optimality: the undamped step would lower the cost by
            ! |U^T r|^2; when that is negligible the iterate is the minimum
            ! (or the data are matched to 1e-9 sigma a row: exact synthetic data)
            if (predicted_decrease(s, u, rr, opts%rcond) <= opts%tol_cost*cost + &
                tiny(1.0_dp) .or. cost <= 1.0e-18_dp*mt) then
                res%converged = .true.
                res%iterations = it - 1
                exit
            end if
            accepted = .false.
            evaluated = .false.
            do trial = 1, opts%max_trials
                dx = lm_step(d, s, u, vt, rr, lambda, opts%rcond)
                pt = p
                pt(free) = min(max(p(free) + dx, lower(free)), upper(free))
                dx = pt(free) - p(free)
                call clear_status(trial_stat)
                call weighted_system(model, y, sigma, pt, free, prior, predt, at, rt, trial_stat)
                if (trial_stat%code == STATUS_OK) then
                    evaluated = .true.
                    cost_t = sum(rt**2)
                    if (cost_t <= cost*(1.0_dp + 8.0_dp*epsilon(1.0_dp)) + tiny(1.0_dp)) then
                        accepted = .true.
                        exit
                    end if
                end if
                lambda = max(10.0_dp*lambda, 1.0e-3_dp*s(1)**2)
            end do
            res%iterations = it
            if (.not. accepted) then
                ! no damped step lowers the cost: a minimum to working precision,
                ! unless the model could not be evaluated near the iterate
                res%converged = evaluated
                if (.not. evaluated) stat = trial_stat
                exit
            end if
            relstep = maxval(abs(dx)/max(abs(p(free)), abs(pt(free)), tiny(1.0_dp)))
            dcost = cost - cost_t
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
            cost = cost_t
            lambda = lambda/10.0_dp
            if (lambda < lam_floor) lambda = 0.0_dp
        end do
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
        call covariance(a, opts, res%cov, res%sigmas, res%corr, res%cond, res%rank, &
                        undetermined, stat)
        if (stat%code /= STATUS_OK) return
        call set_flags(res, params0, lower, upper, undetermined, opts)
        if (.not. res%converged) then
            call set_status(stat, ERR_NO_CONVERGENCE, 'fit', 'Gauss-Newton did not converge '// &
                            'in '//fmt_int(res%iterations)//' iterations (last relative step '// &
                            fmt_real(relstep)//', cost change '//fmt_real(dcost)// &
                            ', chi-square '//fmt_real(res%chi2)//')')
        end if
    end subroutine fit_least_squares

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
            if (x0 /= 0.0_dp .and. abs(x) > opts%runaway_factor*abs(x0)) &
                res%flags(i) = FLAG_RUNAWAY
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
        allocate (res%estimate(nb), res%sigma(nb), res%active(nb), res%direction(mt))
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
            deallocate (d, s, u, vt)
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
            if (ieee_is_finite(sig(j))) then
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

    ! -------------------------------------------------------------- diagnosis

    !> Diagnose a fitted model (`base`, from fit_least_squares): score-test
    !! every candidate block whose parameters are all at their null values and
    !! not free, refit the `nrefit` leading physical candidates with their
    !! parameters freed (likelihood-ratio confirmation), rank, and pick the
    !! verdict: the best candidate whose refit is significant at alpha /
    !! (number tested) (Bonferroni), physical and determined. Candidates that
    !! explain the residuals about as well as the verdict (chi-square drops
    !! within ambiguity_delta, or nearly collinear directions) are marked as
    !! rivals (Akaike-style gains drop - 2 k within ambiguity_delta, or within
    !! twice that when the first-order directions are collinear); when `probe` is present, the probe row whose predictions
    !! differ most between the verdict's and a rival's refits (in units of
    !! probe_sigma) is reported as the measurement that would separate them.
    subroutine diagnose(model, y, sigma, base, null_values, lower, upper, prior, cands, &
                        fopts, dopts, diag, stat, probe, probe_sigma)
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
        integer :: nc, c, k, j, nrefit, best, q
        integer, allocatable :: order(:), tier(:)
        real(dp), allocatable :: key(:), start(:), pa(:), pb(:), jdummy(:, :)
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
            nrefit = nrefit + 1
            associate (cr => diag%cand(c))
                start = base%params
                do j = 1, size(cands(c)%params)
                    k = cands(c)%params(j)
                    if (cr%score%active(j)) start(k) = start(k) + cr%score%estimate(j)
                    start(k) = min(max(start(k), lower(k)), upper(k))
                end do
                call clear_status(st)
                call fit_least_squares(model, y, sigma, start, [base%free, cands(c)%params], &
                                       lower, upper, prior, fopts, cr%refit, st)
                if (st%code /= STATUS_OK .and. st%code /= ERR_NO_CONVERGENCE) then
                    ! the first-order start may be too far: start from the null
                    call clear_status(st)
                    call fit_least_squares(model, y, sigma, base%params, &
                                           [base%free, cands(c)%params], lower, upper, prior, &
                                           fopts, cr%refit, st)
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
