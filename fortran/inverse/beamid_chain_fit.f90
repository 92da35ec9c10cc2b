!> The fit with the measurement chain's row treatments (issue 29): robust
!! losses by iteratively reweighted least squares, sigmas estimated per
!! channel from the residuals, and burn-in rows that are predicted but not
!! fitted. A wrapper of beamid_estimation's fit_least_squares (each pass a
!! plain weighted fit from the last estimates), so the Gauss-Newton search,
!! its bounds and its covariance stay in one place.
!!
!! * Losses: Huber, weights w = min(1, k / |r|) with k = HUBER_K, and
!!   Cauchy, w = 1 / (1 + (r / c)^2) with c = CAUCHY_C (95 % efficiency at
!!   the normal law), on the standardized residuals r = (y - h) / sigma. A
!!   pass fits with sigma / sqrt(w); the passes end when no weight moves by
!!   more than TOL_WEIGHT. The covariance is the last pass's, that of the
!!   reweighted Jacobian.
!! * Unknown sigma: a channel marked for it gets sigma^2 = sum r_raw^2 /
!!   (n_c - k_c), r_raw = y - h over its fitted rows, k_c the sum of their
!!   leverages h_ii = a_i^T C a_i (a_i the weighted row of the Jacobian, C
!!   the covariance: the k free parameters' share of the channel), refitted
!!   until the sigmas settle; its own sigma is sigma / sqrt(2 (n_c - k_c)).
!!   Under a robust loss the rows beyond GROSS_Z are left out of the sum.
!! * Burn-in rows (t before a given time) get weight 0: predicted, shown, not
!!   fitted.
!! The chi-square and degrees of freedom reported count the fitted rows
!! whose standardized residual stays within GROSS_Z (the others are flagged
!! as gross errors), less one degree of freedom per estimated sigma.
module beamid_chain_fit
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK, ERR_INPUT, set_status, fmt_int
    use beamid_estimation, only: residual_model_t, lsq_problem_t, fit_options_t, fit_result_t, &
                                 fit_least_squares
    implicit none
    private

    public :: chain_rows_t, chain_fit, loss_weight, chain_active
    integer, parameter, public :: LOSS_LINEAR = 0, LOSS_HUBER = 1, LOSS_CAUCHY = 2
    real(dp), parameter, public :: HUBER_K = 1.345_dp, CAUCHY_C = 2.3849_dp
    !> standardized residual beyond which a row is flagged as a gross error
    real(dp), parameter, public :: GROSS_Z = 3.5_dp
    integer, parameter :: MAX_PASSES = 40
    real(dp), parameter :: TOL_WEIGHT = 1.0e-3_dp, TOL_SIGMA = 1.0e-4_dp

    !> What the chain asks of each data row.
    type :: chain_rows_t
        integer, allocatable :: loss(:)     !< LOSS_* of the row
        logical, allocatable :: fitted(:)   !< .false.: a burn-in row
        integer, allocatable :: channel(:)  !< channel whose sigma is estimated (0: given)
    end type chain_rows_t

contains

    !> Does the chain change the plain fit (a loss, a burn-in row, a sigma)?
    pure logical function chain_active(rows)
        type(chain_rows_t), intent(in) :: rows
        chain_active = .false.
        if (.not. allocated(rows%loss)) return
        chain_active = any(rows%loss /= LOSS_LINEAR) .or. any(.not. rows%fitted) .or. &
                       any(rows%channel > 0)
    end function chain_active

    !> IRLS weight of a standardized residual r under `loss`.
    elemental real(dp) function loss_weight(loss, r) result(w)
        integer, intent(in) :: loss
        real(dp), intent(in) :: r
        select case (loss)
        case (LOSS_HUBER)
            w = 1.0_dp
            if (abs(r) > HUBER_K) w = HUBER_K/abs(r)
        case (LOSS_CAUCHY)
            w = 1.0_dp/(1.0_dp + (r/CAUCHY_C)**2)
        case default
            w = 1.0_dp
        end select
    end function loss_weight

    !> The fit with the rows' losses, burn-in and estimated sigmas. weights:
    !! the last pass's weight of every row (0 for burn-in); sigma: the sigma
    !! each row was judged with (the estimate for an estimated channel);
    !! sigma_sd: its standard deviation (0 where given); flagged: fitted rows
    !! beyond GROSS_Z.
    subroutine chain_fit(model, lp, params0, free, opts, rows, res, weights, sigma, sigma_sd, &
                         flagged, stat)
        class(residual_model_t), intent(inout) :: model
        type(lsq_problem_t), intent(in) :: lp
        real(dp), intent(in) :: params0(:)
        integer, intent(in) :: free(:)
        type(fit_options_t), intent(in) :: opts
        type(chain_rows_t), intent(in) :: rows
        type(fit_result_t), intent(out) :: res
        real(dp), intent(out) :: weights(:), sigma(:), sigma_sd(:)
        logical, intent(out) :: flagged(:)
        type(status_t), intent(inout) :: stat
        type(lsq_problem_t) :: lw
        real(dp), allocatable :: p(:), r(:), wnew(:), snew(:), lev(:), pred(:), jac(:, :)
        integer :: pass, c, nchan, i, nest
        real(dp) :: nc, kc, ss
        logical :: settled
        nchan = 0
        if (size(rows%channel) > 0) nchan = maxval(rows%channel)
        weights = merge(1.0_dp, 0.0_dp, rows%fitted)
        sigma = lp%sigma
        call start_sigmas(lp%y, rows%channel, sigma, stat)
        if (stat%code /= STATUS_OK) return
        sigma_sd = 0.0_dp
        p = params0
        lw = lp
        allocate (lev(size(lp%y)), source=0.0_dp)
        do pass = 1, MAX_PASSES
            lw%sigma = sigma/sqrt(max(weights, 1.0e-200_dp))
            call fit_least_squares(model, lw, p, free, opts, res, stat)
            if (stat%code /= STATUS_OK) return
            p = res%params
            r = (lp%y - res%predictions)/sigma
            snew = sigma
            if (nchan > 0) then
                ! leverages of the fitted rows from the reweighted Jacobian
                allocate (pred(size(lp%y)), jac(size(lp%y), size(free)))
                call model%evaluate(p, free, pred, jac, stat)
                if (stat%code /= STATUS_OK) return
                do i = 1, size(lp%y)
                    jac(i, :) = jac(i, :)/lw%sigma(i)
                end do
                lev = 0.0_dp
                if (all(ieee_is_finite(res%cov))) then
                    do i = 1, size(lp%y)
                        lev(i) = dot_product(jac(i, :), matmul(res%cov, jac(i, :)))
                    end do
                end if
                deallocate (pred, jac)
                do c = 1, nchan
                    ! under a robust loss the rows beyond GROSS_Z (at the last
                    ! sigma) are gross errors, not noise: left out of the sum
                    associate (in_c => rows%channel == c .and. rows%fitted .and. &
                               (rows%loss == LOSS_LINEAR .or. abs(r) <= GROSS_Z))
                        nc = real(count(in_c), dp)
                        kc = sum(lev, mask=in_c)
                        if (nc - kc <= 0.5_dp) cycle
                        ss = sum((lp%y - res%predictions)**2, mask=in_c)
                        where (rows%channel == c) snew = sqrt(ss/(nc - kc))
                        where (rows%channel == c) sigma_sd = snew/sqrt(2.0_dp*(nc - kc))
                    end associate
                end do
                r = (lp%y - res%predictions)/snew
            end if
            wnew = merge(loss_weight(rows%loss, r), 0.0_dp, rows%fitted)
            settled = all(abs(wnew - weights) < TOL_WEIGHT) .and. &
                      all(abs(snew/sigma - 1.0_dp) < TOL_SIGMA)
            weights = wnew
            sigma = snew
            if (settled .and. pass > 1) exit
            if (settled .and. nchan == 0 .and. all(rows%loss == 0)) exit
        end do
        ! the rows as judged: the sigmas used, gross errors flagged, the
        ! chi-square of the fitted rows that are not
        res%normalized = (lp%y - res%predictions)/sigma
        flagged = rows%fitted .and. abs(res%normalized) > GROSS_Z
        nest = 0
        do c = 1, nchan
            if (any(rows%channel == c .and. rows%fitted)) nest = nest + 1
        end do
        res%chi2 = sum(res%normalized**2, mask=rows%fitted .and. .not. flagged)
        res%dof = res%dof - count(.not. rows%fitted) - count(flagged) - nest
        res%row_sigma = sigma
        res%row_weight = weights
        res%row_gross = flagged
        res%row_sigma_sd = sigma_sd
    end subroutine chain_fit

    !> The rows' sigmas where not given (NaN: an empty sigma field): the
    !! start of an estimated channel's sigma (the mean of its given sigmas,
    !! else the spread of its values, else 1; the passes estimate it);
    !! ERR_INPUT for a row without sigma whose channel is not estimated.
    pure subroutine start_sigmas(y, channel, sigma, stat)
        real(dp), intent(in) :: y(:)
        integer, intent(in) :: channel(:)
        real(dp), intent(inout) :: sigma(:)
        type(status_t), intent(inout) :: stat
        logical :: none(size(sigma))
        integer :: c, i, n
        real(dp) :: start, mean
        none = ieee_is_nan(sigma)
        if (.not. any(none)) return
        do i = 1, size(sigma)
            if (none(i) .and. channel(i) == 0) then
                call set_status(stat, ERR_INPUT, 'fit', 'sigma missing: row '//fmt_int(i)// &
                                ' has no sigma and no estimation is asked for its '// &
                                'channel; expected a sigma > 0 on every row or its '// &
                                "channel's sigma estimated (estimate_sigma)")
                return
            end if
        end do
        do c = 1, maxval(channel)
            if (.not. any(none .and. channel == c)) cycle
            n = count(channel == c .and. .not. none)
            if (n > 0) then
                start = sum(sigma, mask=channel == c .and. .not. none)/real(n, dp)
            else
                n = count(channel == c)
                mean = sum(y, mask=channel == c)/real(n, dp)
                start = sqrt(sum((y - mean)**2, mask=channel == c)/real(max(n - 1, 1), dp))
                if (.not. start > 0.0_dp) start = 1.0_dp
            end if
            where (none .and. channel == c) sigma = start
        end do
    end subroutine start_sigmas
end module beamid_chain_fit
