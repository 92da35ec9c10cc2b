!> Experiment design and Monte Carlo consistency of an estimate.
!!
!! Nothing here knows about beams or experiment families: the inputs are a
!! Fisher information matrix over the free parameters (J^T W J of the fit's
!! weighted rows plus the a priori rows of Eq. 142-145, i.e. the inverse of
!! the covariance of Eq. 55), sensitivity rows of candidate measurements and
!! their sigmas, or the estimates and sigmas of Monte Carlo replicates.
!!
!! * `information_add_row`: the information after one more measurement,
!!   I + g g^T / sigma^2 (weights of Eq. 53-54);
!! * `information_covariance`: the covariance (Eq. 55) of an information
!!   matrix from its column-scaled symmetric eigen-decomposition (cyclic
!!   Jacobi), with the same rule as the fit's SVD covariance: a direction
!!   below the rank cutoff is not inverted and a parameter with a component
!!   in it gets an infinite sigma; also the D-criterion det(cov)^(1/(2n))
!!   (the geometric mean sigma of the joint confidence ellipsoid);
!! * `rank_candidates`: the predicted sigma of one target parameter (or the
!!   D-criterion) after adding each candidate row, and the ranking;
!! * `mc_summary`: coverage within 1, 2, 3 sigma, bias, empirical spread and
!!   the ratio of reported to empirical sigma over replicates.
!!
!! Everything is pure; sizes come from the arguments (no caps).
module beamid_design
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use beamid_kinds, only: dp, infinity, not_a_number
    use beamid_status, only: status_t, set_status, STATUS_OK, ERR_INPUT, fmt_int, fmt_real
    use beamid_estimation, only: sort_desc
    implicit none
    private

    public :: information_add_row, information_covariance, rank_candidates, mc_summary

    !> Relative cutoff on the eigenvalues of the scaled information (the
    !! squares of the fit's singular values; the fit cuts those at 1e-10 of
    !! the largest, i.e. 1e-20 here, below what an eigen-decomposition of
    !! J^T W J resolves, so the cutoff is the one a double can see).
    real(dp), parameter, public :: INFO_RCOND = 1.0e-13_dp

contains

    !> info <- info + g g^T / sigma^2 (one more measurement of sigma with
    !! sensitivity row g over the free parameters).
    pure subroutine information_add_row(info, g, sigma)
        real(dp), intent(inout) :: info(:, :)
        real(dp), intent(in) :: g(:), sigma
        integer :: j
        do j = 1, size(g)
            info(:, j) = info(:, j) + g*g(j)/sigma**2
        end do
    end subroutine information_add_row

    !> Eigen-decomposition of a symmetric matrix by cyclic Jacobi rotations:
    !! a = v diag(w) v^T. Small n (the free parameters of a fit).
    pure subroutine jacobi_eigen(a, w, v)
        real(dp), intent(in) :: a(:, :)
        real(dp), intent(out) :: w(:), v(:, :)
        real(dp) :: b(size(a, 1), size(a, 1)), off, total, theta, t, c, s, bpq
        real(dp) :: colp(size(a, 1)), colq(size(a, 1))
        integer :: n, p, q, sweep, i
        n = size(a, 1)
        b = a
        v = 0.0_dp
        do i = 1, n
            v(i, i) = 1.0_dp
        end do
        do sweep = 1, 100
            off = 0.0_dp
            total = 0.0_dp
            do q = 1, n
                do p = 1, n
                    total = total + b(p, q)**2
                    if (p /= q) off = off + b(p, q)**2
                end do
            end do
            if (off <= (epsilon(1.0_dp)**2)*total .or. off == 0.0_dp) exit
            do p = 1, n - 1
                do q = p + 1, n
                    bpq = b(p, q)
                    if (bpq == 0.0_dp) cycle
                    theta = (b(q, q) - b(p, p))/(2.0_dp*bpq)
                    t = sign(1.0_dp, theta)/(abs(theta) + sqrt(theta**2 + 1.0_dp))
                    c = 1.0_dp/sqrt(t**2 + 1.0_dp)
                    s = t*c
                    ! rotate columns p and q, then rows p and q (b <- J^T b J)
                    colp = b(:, p)
                    colq = b(:, q)
                    b(:, p) = c*colp - s*colq
                    b(:, q) = s*colp + c*colq
                    colp = b(p, :)
                    colq = b(q, :)
                    b(p, :) = c*colp - s*colq
                    b(q, :) = s*colp + c*colq
                    b(p, q) = 0.0_dp
                    b(q, p) = 0.0_dp
                    colp = v(:, p)
                    colq = v(:, q)
                    v(:, p) = c*colp - s*colq
                    v(:, q) = s*colp + c*colq
                end do
            end do
        end do
        do i = 1, n
            w(i) = b(i, i)
        end do
    end subroutine jacobi_eigen

    !> Covariance of an information matrix (n x n, symmetric, positive
    !! semi-definite). Columns are scaled to a unit diagonal first (as the
    !! fit scales its Jacobian columns); eigenvalues below INFO_RCOND times
    !! the largest are not inverted. A parameter with a component of more
    !! than 1e-6 in such a direction gets sigma = +Inf (undetermined), as in
    !! the fit. d_crit = det(cov)^(1/(2n)) over the kept directions, +Inf
    !! when rank < n. A non-symmetric or non-finite matrix is bad input.
    pure subroutine information_covariance(info, cov, sig, d_crit, rank, stat)
        real(dp), intent(in) :: info(:, :)
        real(dp), intent(out) :: cov(:, :), sig(:), d_crit
        integer, intent(out) :: rank
        type(status_t), intent(inout) :: stat
        real(dp) :: d(size(info, 1)), scaled(size(info, 1), size(info, 1))
        real(dp) :: w(size(info, 1)), v(size(info, 1), size(info, 1)), wmax, logdet
        logical :: kept(size(info, 1))
        integer :: n, i, j, k
        n = size(info, 1)
        cov = 0.0_dp
        sig = infinity()
        d_crit = infinity()
        rank = 0
        if (size(info, 2) /= n .or. size(cov, 1) /= n .or. size(cov, 2) /= n .or. &
            size(sig) /= n) then
            call set_status(stat, ERR_INPUT, 'information_covariance', 'shapes do not match '// &
                            'an information matrix of order '//fmt_int(n))
            return
        end if
        if (n == 0) return
        if (.not. all(ieee_is_finite(info))) then
            call set_status(stat, ERR_INPUT, 'information_covariance', &
                            'information matrix has non-finite entries')
            return
        end if
        do j = 1, n
            do i = 1, j - 1
                if (abs(info(i, j) - info(j, i)) > 1.0e-10_dp*max(abs(info(i, j)), &
                    abs(info(j, i)), sqrt(abs(info(i, i)*info(j, j))), tiny(1.0_dp))) then
                    call set_status(stat, ERR_INPUT, 'information_covariance', &
                                    'information matrix is not symmetric (entry '// &
                                    fmt_int(i)//','//fmt_int(j)//' = '//fmt_real(info(i, j))// &
                                    ', transposed '//fmt_real(info(j, i))//')')
                    return
                end if
            end do
            if (info(j, j) < 0.0_dp) then
                call set_status(stat, ERR_INPUT, 'information_covariance', 'diagonal entry '// &
                                fmt_int(j)//' = '//fmt_real(info(j, j))//', expected >= 0')
                return
            end if
        end do
        do j = 1, n
            d(j) = sqrt(info(j, j))
            if (d(j) <= tiny(1.0_dp)) d(j) = 1.0_dp
        end do
        do j = 1, n
            scaled(:, j) = 0.5_dp*(info(:, j) + info(j, :))/d/d(j)
        end do
        call jacobi_eigen(scaled, w, v)
        wmax = maxval(w)
        kept = .false.
        if (wmax > 0.0_dp) kept = w > INFO_RCOND*wmax
        rank = count(kept)
        logdet = 0.0_dp
        do k = 1, n
            if (.not. kept(k)) cycle
            logdet = logdet + log(w(k))
            do j = 1, n
                cov(:, j) = cov(:, j) + v(:, k)*v(j, k)/w(k)
            end do
        end do
        do j = 1, n
            cov(:, j) = cov(:, j)/d/d(j)
        end do
        do i = 1, n
            if (rank == n) then
                sig(i) = sqrt(max(cov(i, i), 0.0_dp))
            else if (1.0_dp - sum(v(i, :)**2, mask=kept) <= 1.0e-6_dp) then
                sig(i) = sqrt(max(cov(i, i), 0.0_dp))
            end if
        end do
        if (rank == n) d_crit = exp(-(logdet + 2.0_dp*sum(log(d)))/(2.0_dp*n))
    end subroutine information_covariance

    !> Predicted criterion after each candidate measurement: the sigma of
    !! parameter `target` (1-based into the free parameters) or, with
    !! target = 0, the D-criterion det(cov)^(1/(2n)). rows(:, c) is the
    !! sensitivity of candidate c over the free parameters, sigma(c) its
    !! standard deviation. base = the criterion with no new measurement.
    !! order lists the candidates best (smallest criterion) first; ties keep
    !! the candidates' order. crit(c) = +Inf when the target stays undetermined.
    pure subroutine rank_candidates(info, rows, sigma, target, base, crit, order, stat)
        real(dp), intent(in) :: info(:, :), rows(:, :), sigma(:)
        integer, intent(in) :: target
        real(dp), intent(out) :: base, crit(:)
        integer, intent(out) :: order(:)
        type(status_t), intent(inout) :: stat
        real(dp) :: work(size(info, 1), size(info, 1)), cov(size(info, 1), size(info, 1))
        real(dp) :: sig(size(info, 1)), dc
        integer :: n, nc, c, rank
        n = size(info, 1)
        nc = size(sigma)
        base = infinity()
        crit = infinity()
        order = [(c, c = 1, size(order))]
        if (size(rows, 1) /= n .or. size(rows, 2) /= nc .or. size(crit) /= nc .or. &
            size(order) /= nc) then
            call set_status(stat, ERR_INPUT, 'rank_candidates', 'candidate rows are '// &
                            fmt_int(size(rows, 1))//'x'//fmt_int(size(rows, 2))//' for '// &
                            fmt_int(n)//' free parameters and '//fmt_int(nc)//' sigmas')
            return
        end if
        if (target < 0 .or. target > n) then
            call set_status(stat, ERR_INPUT, 'rank_candidates', 'target index '// &
                            fmt_int(target)//' outside 0..'//fmt_int(n))
            return
        end if
        do c = 1, nc
            if (.not. (sigma(c) > 0.0_dp .and. ieee_is_finite(sigma(c)))) then
                call set_status(stat, ERR_INPUT, 'rank_candidates', 'candidate '//fmt_int(c)// &
                                ' sigma = '//fmt_real(sigma(c))//', expected sigma > 0')
                return
            end if
            if (.not. all(ieee_is_finite(rows(:, c)))) then
                call set_status(stat, ERR_INPUT, 'rank_candidates', 'candidate '//fmt_int(c)// &
                                ' has non-finite sensitivities')
                return
            end if
        end do
        call information_covariance(info, cov, sig, dc, rank, stat)
        if (stat%code /= STATUS_OK) return
        base = criterion(sig, dc)
        do c = 1, nc
            work = info
            call information_add_row(work, rows(:, c), sigma(c))
            call information_covariance(work, cov, sig, dc, rank, stat)
            if (stat%code /= STATUS_OK) return
            crit(c) = criterion(sig, dc)
        end do
        ! ascending, stable (+Inf last, ties in candidate order; crit is never NaN)
        order = sort_desc(-crit)
    contains
        pure real(dp) function criterion(s, dcrit)
            real(dp), intent(in) :: s(:), dcrit
            if (target == 0) then
                criterion = dcrit
            else
                criterion = s(target)
            end if
        end function criterion
    end subroutine rank_candidates

    !> Monte Carlo summary over replicates r = 1..nrep of parameters j:
    !! the normalized error z = (est - truth) / sigma of every replicate with
    !! use(r) and finite est, sigma > 0 counts; coverage(k, j) = fraction with
    !! |z| <= k (k = 1, 2, 3), bias(j) = mean(est - truth), spread(j) = sample
    !! standard deviation of est, mean_sigma(j) = root mean square reported
    !! sigma, ratio(j) = mean_sigma / spread (1 when the sigmas are honest),
    !! zmean, zstd = mean and standard deviation of z, nused(j) = the count.
    !! Undefined entries (fewer than 2 replicates) are NaN.
    pure subroutine mc_summary(est, sig, truth, use, coverage, bias, spread, mean_sigma, &
                               ratio, zmean, zstd, nused)
        real(dp), intent(in) :: est(:, :), sig(:, :), truth(:)
        logical, intent(in) :: use(:)
        real(dp), intent(out) :: coverage(:, :), bias(:), spread(:), mean_sigma(:), ratio(:)
        real(dp), intent(out) :: zmean(:), zstd(:)
        integer, intent(out) :: nused(:)
        integer :: j, r, k, m
        real(dp) :: z, emean, inside(3), zsum, zsq, ssq, esq
        do j = 1, size(truth)
            m = 0
            inside = 0.0_dp
            emean = 0.0_dp
            zsum = 0.0_dp
            zsq = 0.0_dp
            ssq = 0.0_dp
            do r = 1, size(est, 1)
                if (.not. ok(r, j)) cycle
                m = m + 1
                z = (est(r, j) - truth(j))/sig(r, j)
                do k = 1, 3
                    if (abs(z) <= real(k, dp)) inside(k) = inside(k) + 1.0_dp
                end do
                emean = emean + est(r, j)
                zsum = zsum + z
                ssq = ssq + sig(r, j)**2
            end do
            nused(j) = m
            coverage(:, j) = not_a_number()
            bias(j) = not_a_number()
            spread(j) = not_a_number()
            mean_sigma(j) = not_a_number()
            ratio(j) = not_a_number()
            zmean(j) = not_a_number()
            zstd(j) = not_a_number()
            if (m == 0) cycle
            coverage(:, j) = inside/real(m, dp)
            emean = emean/real(m, dp)
            zsum = zsum/real(m, dp)
            bias(j) = emean - truth(j)
            mean_sigma(j) = sqrt(ssq/real(m, dp))
            zmean(j) = zsum
            if (m < 2) cycle
            esq = 0.0_dp
            zsq = 0.0_dp
            do r = 1, size(est, 1)
                if (.not. ok(r, j)) cycle
                esq = esq + (est(r, j) - emean)**2
                zsq = zsq + ((est(r, j) - truth(j))/sig(r, j) - zsum)**2
            end do
            spread(j) = sqrt(esq/real(m - 1, dp))
            zstd(j) = sqrt(zsq/real(m - 1, dp))
            if (spread(j) > 0.0_dp) ratio(j) = mean_sigma(j)/spread(j)
        end do
    contains
        pure logical function ok(r, j)
            integer, intent(in) :: r, j
            ok = use(r) .and. ieee_is_finite(est(r, j)) .and. ieee_is_finite(sig(r, j))
            if (ok) ok = sig(r, j) > 0.0_dp
        end function ok
    end subroutine mc_summary
end module beamid_design
