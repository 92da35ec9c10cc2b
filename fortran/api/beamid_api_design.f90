!> f2py-facing API for experiment design and Monte Carlo summaries
!! (beamid_design). Indices are 1-based; logical inputs are 0/1 integers.
module beamid_api_design
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, status_out
    use beamid_estimation, only: chi2_sf
    use beamid_design, only: information_covariance, rank_candidates, mc_summary, &
                             information_add_row
    implicit none
    private

    public :: api_information_covariance, api_rank_candidates, api_mc_summary
    public :: api_chi2_sf_many, api_information_update

contains

    !> Covariance, sigmas, D-criterion det(cov)^(1/(2n)) and rank of an
    !! information matrix.
    subroutine api_information_covariance(n, info, cov, sig, d_crit, rank, code, message)
        integer(c_int), intent(in) :: n
        real(c_double), intent(in) :: info(n, n)
        real(c_double), intent(out) :: cov(n, n), sig(n), d_crit
        integer(c_int), intent(out) :: rank, code
        character(len=256), intent(out) :: message
        type(status_t) :: stat
        call information_covariance(real(info, dp), cov, sig, d_crit, rank, stat)
        call status_out(stat, code, message)
    end subroutine api_information_covariance

    !> Predicted sigma of free parameter `target` (0: D-criterion) after each
    !! candidate row; order = candidates best first.
    subroutine api_rank_candidates(n, info, nc, rows, sigma, target, base, crit, order, &
                                   code, message)
        integer(c_int), intent(in) :: n, nc, target
        real(c_double), intent(in) :: info(n, n), rows(n, nc), sigma(nc)
        real(c_double), intent(out) :: base, crit(nc)
        integer(c_int), intent(out) :: order(nc), code
        character(len=256), intent(out) :: message
        type(status_t) :: stat
        call rank_candidates(real(info, dp), real(rows, dp), real(sigma, dp), int(target), base, &
                             crit, order, stat)
        call status_out(stat, code, message)
    end subroutine api_rank_candidates

    !> Information after measurement rows: info + sum_c rows(:, c) rows(:, c)^T
    !! / sigma(c)^2 (beamid_design::information_add_row).
    subroutine api_information_update(n, info, nc, rows, sigma, updated)
        integer(c_int), intent(in) :: n, nc
        real(c_double), intent(in) :: info(n, n), rows(n, nc), sigma(nc)
        real(c_double), intent(out) :: updated(n, n)
        integer :: c
        updated = info
        do c = 1, nc
            call information_add_row(updated, real(rows(:, c), dp), real(sigma(c), dp))
        end do
    end subroutine api_information_update

    !> Monte Carlo summary (beamid_design::mc_summary); est and sig are
    !! nrep x npar, use is 0/1 per replicate. stats(:, j) = coverage 1, 2, 3
    !! sigma, bias, spread, rms sigma, ratio, z mean, z std, count.
    subroutine api_mc_summary(nrep, npar, est, sig, truth, use, stats)
        integer(c_int), intent(in) :: nrep, npar
        real(c_double), intent(in) :: est(nrep, npar), sig(nrep, npar), truth(npar)
        integer(c_int), intent(in) :: use(nrep)
        real(c_double), intent(out) :: stats(10, npar)
        integer :: nused(npar)
        call mc_summary(real(est, dp), real(sig, dp), real(truth, dp), use /= 0, stats(1:3, :), &
                        stats(4, :), stats(5, :), stats(6, :), stats(7, :), stats(8, :), &
                        stats(9, :), nused)
        stats(10, :) = real(nused, dp)
    end subroutine api_mc_summary

    !> Chi-square survival function of many values (p-values of replicate
    !! chi-squares against their dof).
    subroutine api_chi2_sf_many(n, x, k, p)
        integer(c_int), intent(in) :: n
        real(c_double), intent(in) :: x(n)
        integer(c_int), intent(in) :: k(n)
        real(c_double), intent(out) :: p(n)
        integer :: i
        do i = 1, n
            p(i) = chi2_sf(real(x(i), dp), int(k(i)))
        end do
    end subroutine api_chi2_sf_many
end module beamid_api_design
