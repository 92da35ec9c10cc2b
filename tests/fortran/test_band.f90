!> The band kernels of the integrators against their defining equations:
!! the band LU with partial pivoting (band_factor/band_solve and the complex
!! zband_factor/zband_solve of beamid_dynamics, LAPACK's dgbtf2/dgbtrs
!! written out), the L D L^T without pivoting of the symmetric iteration
!! matrices and the band products (ldlt_real, ldlt_cplx, their solves,
!! dband_mv, zband_mv of beamid_integrators). Residuals are checked as
!! LAPACK's tests do: ||b - A x|| / (||A|| ||x|| n eps) below 30; matrices
!! that need row interchanges, one-sided bands, a dense matrix stored as a
!! band, and the failures (a singular band, a zero complex pivot, a pivot
!! that is not positive); the assembly helpers (band_add, band_to_dense,
!! band_mv on an assembly array) and the solves with several right-hand
!! sides, real and complex, against dense ones; the inertia count of an
!! indefinite band matrix L D L^T against the signs of D.
program test_band
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK
    use beamid_band, only: band_lu_t, zband_lu_t, band_factor, band_solve, zband_factor, &
                           zband_solve, ldlt_real, ldlt_cplx, ldlt_solve_real, ldlt_solve_cplx, &
                           ldlt_solve_real_many, ldlt_solve_cplx_many, &
                           dband_mv, zband_mv, band_add, band_to_dense, band_mv, ldlt_inertia
    use beamid_testing, only: checks_t, check_close, check_below, check_true, check_finish, &
                              seed_random
    implicit none

    !> LAPACK's threshold for the scaled residual ratio.
    real(dp), parameter :: THRESH = 30.0_dp
    type(checks_t) :: t
    integer :: i, n
    integer, parameter :: sizes(3, 5) = reshape([1, 0, 0, 5, 1, 2, 33, 7, 7, 40, 3, 7, &
                                                 12, 11, 11], [3, 5])
    integer, parameter :: edges(3, 4) = reshape([30, 0, 3, 30, 3, 0, 300, 7, 7, 8, 7, 7], &
                                                [3, 4])
    integer, parameter :: ldlt_n(8) = [1, 5, 8, 9, 14, 15, 33, 100], ldlt_k(3) = [7, 3, 0]

    call seed_random(11)
    do i = 1, size(sizes, 2)
        call band_lu(sizes(1, i), sizes(2, i), sizes(3, i), .false.)
        call band_lu(sizes(1, i), sizes(2, i), sizes(3, i), .true.)
    end do
    ! one-sided bands, a long chain, a dense matrix stored as a band (the
    ! modal systems); rows are swapped (weak diagonal) on two-sided bands only
    do i = 1, size(edges, 2)
        call band_lu(edges(1, i), edges(2, i), edges(3, i), edges(2, i) > 0 .and. edges(3, i) > 0)
    end do
    call singular_band()
    call singular_complex_band()
    ! half-bandwidth 7, the rigid chain's, has constant trip-count paths: n
    ! below, at and above 7 and 2 x 7 cover their edges
    do n = 1, size(ldlt_n)
        do i = 1, size(ldlt_k)
            call symmetric_band(ldlt_n(n), min(ldlt_k(i), ldlt_n(n) - 1))
        end do
    end do
    call symmetric_band_refuses_bad_pivots()
    call assembly_helpers(9, 2, 3)
    call assembly_helpers(20, 7, 7)
    call inertia(12, 1)
    call inertia(30, 7)
    call check_finish(t, 'test_band')

contains

    function normal(m, n) result(a)
        integer, intent(in) :: m, n
        real(dp) :: a(m, n), u(m, n), v(m, n)
        call random_number(u)
        call random_number(v)
        a = sqrt(-2.0_dp*log(1.0_dp - u))*cos(8.0_dp*atan(1.0_dp)*v)
    end function normal

    !> A random band matrix (kl, ku); a weak diagonal makes partial pivoting
    !! swap rows, else the diagonal dominates.
    function band_matrix(n, kl, ku, weak) result(a)
        integer, intent(in) :: n, kl, ku
        logical, intent(in) :: weak
        real(dp) :: a(n, n)
        integer :: i, j
        a = normal(n, n)
        do j = 1, n
            do i = 1, n
                if (i - j > kl .or. j - i > ku) a(i, j) = 0.0_dp
            end do
            if (weak) then
                a(j, j) = 1.0e-3_dp*a(j, j)
            else
                a(j, j) = a(j, j) + 2.0_dp*(kl + ku + 1)
            end if
        end do
    end function band_matrix

    !> ||b - A x||_1 / (||A||_1 ||x||_1 n eps), real or complex.
    real(dp) function ratio(a, x, b)
        complex(dp), intent(in) :: a(:, :), x(:), b(:)
        real(dp) :: anorm
        anorm = maxval(sum(abs(a), dim=1))
        ratio = sum(abs(b - matmul(a, x)))/(anorm*sum(abs(x))*size(x)*epsilon(1.0_dp))
    end function ratio

    subroutine band_lu(n, kl, ku, weak)
        integer, intent(in) :: n, kl, ku
        logical, intent(in) :: weak
        type(band_lu_t) :: lu
        type(zband_lu_t) :: zlu
        type(status_t) :: stat
        real(dp) :: a(n, n), b(n, n), r(n), s(n), x(n)
        complex(dp) :: z(n)
        character(len=64) :: label
        integer :: i, j
        write (label, '(a, 3(i0, 1x), l1)') 'band LU n kl ku weak: ', n, kl, ku, weak
        a = band_matrix(n, kl, ku, weak)
        b = 0.3_dp*band_matrix(n, kl, ku, .false.)
        r = reshape(normal(n, 1), [n])
        s = reshape(normal(n, 1), [n])
        lu%n = n
        lu%kl = kl
        lu%ku = ku
        zlu%n = n
        zlu%kl = kl
        zlu%ku = ku
        allocate (lu%ab(2*kl + ku + 1, n), zlu%ab(2*kl + ku + 1, n))
        lu%ab = 0.0_dp
        zlu%ab = (0.0_dp, 0.0_dp)
        do j = 1, n
            do i = max(1, j - ku), min(n, j + kl)
                lu%ab(kl + ku + 1 + i - j, j) = a(i, j)
                zlu%ab(kl + ku + 1 + i - j, j) = cmplx(a(i, j), b(i, j), dp)
            end do
        end do
        call band_factor(lu, stat)
        call check_true(t, trim(label)//': factored', stat%code == STATUS_OK)
        if (stat%code /= STATUS_OK) return
        x = r
        call band_solve(lu, x)
        call check_below(t, trim(label)//': real residual ratio', &
                         ratio(cmplx(a, 0.0_dp, dp), cmplx(x, 0.0_dp, dp), &
                               cmplx(r, 0.0_dp, dp)), THRESH)
        call zband_factor(zlu, stat)
        call check_true(t, trim(label)//': complex factored', stat%code == STATUS_OK)
        if (stat%code /= STATUS_OK) return
        z = cmplx(r, s, dp)
        call zband_solve(zlu, z)
        call check_below(t, trim(label)//': complex residual ratio', &
                         ratio(cmplx(a, b, dp), z, cmplx(r, s, dp)), THRESH)
    end subroutine band_lu

    subroutine singular_band()
        type(band_lu_t) :: lu
        type(status_t) :: stat
        lu%n = 4
        lu%kl = 1
        lu%ku = 1
        allocate (lu%ab(4, 4))
        lu%ab = 0.0_dp
        lu%ab(3, :) = [1.0_dp, 2.0_dp, 0.0_dp, 4.0_dp]
        call band_factor(lu, stat)
        call check_true(t, 'a singular band is a numerical failure naming it: '// &
                        trim(stat%message), stat%code > 0 .and. index(stat%message, 'singular') > 0)
    end subroutine singular_band

    !> A = [[0, 1], [1, 0]] is regular, A + iB = [[i, 1], [1, -i]] is not: the
    !! complex factorization meets a zero pivot in column 2.
    subroutine singular_complex_band()
        type(zband_lu_t) :: zlu
        type(status_t) :: stat
        zlu%n = 2
        zlu%kl = 1
        zlu%ku = 1
        allocate (zlu%ab(4, 2))
        zlu%ab = (0.0_dp, 0.0_dp)
        zlu%ab(3, :) = [(0.0_dp, 1.0_dp), (0.0_dp, -1.0_dp)]   ! diagonal
        zlu%ab(2, 2) = (1.0_dp, 0.0_dp)                        ! A(1, 2)
        zlu%ab(4, 1) = (1.0_dp, 0.0_dp)                        ! A(2, 1)
        call zband_factor(zlu, stat)
        call check_true(t, 'a zero complex pivot is reported with its column: '// &
                        trim(stat%message), stat%code > 0 .and. &
                        index(stat%message, 'zero pivot 2') > 0)
    end subroutine singular_complex_band

    function symmetric_matrix(n, k, shift) result(a)
        integer, intent(in) :: n, k
        real(dp), intent(in) :: shift
        real(dp) :: a(n, n)
        integer :: i, j
        a = normal(n, n)
        a = a + transpose(a)
        do j = 1, n
            do i = 1, n
                if (abs(i - j) > k) a(i, j) = 0.0_dp
            end do
            a(j, j) = a(j, j) + shift
        end do
    end function symmetric_matrix

    !> The Radau iteration matrices lam^2 M + lam C + K are factored as
    !! L D L^T without pivoting (real: positive definite; complex: positive
    !! definite imaginary part); band products against dense ones.
    subroutine symmetric_band(n, k)
        integer, intent(in) :: n, k
        real(dp) :: a(n, n), b(n, n), r(n), s(n), x(n), s1(k + 1, n), g1(3*k + 1, n), ax(n)
        complex(dp) :: s2(k + 1, n), g2(3*k + 1, n), z(n), az(n), zm(2, n)
        real(dp) :: bm(3, n)
        character(len=64) :: label
        logical :: ok
        integer :: i, j
        write (label, '(a, 2(i0, 1x))') 'L D L^T n k: ', n, k
        a = symmetric_matrix(n, k, 4.0_dp*(2*k + 1) + 12.0_dp)          ! diagonally dominant
        b = 0.5_dp*symmetric_matrix(n, k, 4.0_dp*(2*k + 1) + 12.0_dp)   ! SPD imaginary part
        r = reshape(normal(n, 1), [n])
        s = reshape(normal(n, 1), [n])
        s1 = 0.0_dp
        s2 = (0.0_dp, 0.0_dp)
        g1 = 0.0_dp
        g2 = (0.0_dp, 0.0_dp)
        do j = 1, n
            do i = max(1, j - k), min(n, j + k)
                g1(2*k + 1 + i - j, j) = a(i, j)
                g2(2*k + 1 + i - j, j) = cmplx(a(i, j), b(i, j), dp)
                if (i >= j) then
                    s1(1 + i - j, j) = a(i, j)
                    s2(1 + i - j, j) = cmplx(a(i, j), b(i, j), dp)
                end if
            end do
        end do
        call dband_mv(n, k, k, g1, r, ax)
        call check_close(t, trim(label)//': band product', ax, matmul(a, r), 1.0e-13_dp, &
                         1.0e-13_dp)
        call zband_mv(n, k, k, g2, cmplx(r, s, dp), az)
        call check_close(t, trim(label)//': complex band product (real part)', real(az, dp), &
                         real(matmul(cmplx(a, b, dp), cmplx(r, s, dp)), dp), 1.0e-13_dp, 1.0e-13_dp)
        call check_close(t, trim(label)//': complex band product (imaginary part)', aimag(az), &
                         aimag(matmul(cmplx(a, b, dp), cmplx(r, s, dp))), 1.0e-13_dp, 1.0e-13_dp)
        call ldlt_real(n, k, s1, ok)
        call check_true(t, trim(label)//': real factored', ok)
        x = r
        call ldlt_solve_real(n, k, s1, x)
        call check_below(t, trim(label)//': real residual ratio', &
                         ratio(cmplx(a, 0.0_dp, dp), cmplx(x, 0.0_dp, dp), &
                               cmplx(r, 0.0_dp, dp)), THRESH)
        call ldlt_cplx(n, k, s2, ok)
        call check_true(t, trim(label)//': complex factored', ok)
        z = cmplx(r, s, dp)
        call ldlt_solve_cplx(n, k, s2, z)
        call check_below(t, trim(label)//': complex residual ratio', &
                         ratio(cmplx(a, b, dp), z, cmplx(r, s, dp)), THRESH)
        ! three right-hand sides at once (rows of bm): the same solutions as
        ! one at a time, to rounding
        bm(1, :) = r
        bm(2, :) = s
        bm(3, :) = r - 2.0_dp*s
        call ldlt_solve_real_many(n, k, s1, 3, bm)
        call check_close(t, trim(label)//': real many-column solve', bm(1, :), x, &
                         1.0e-13_dp, 1.0e-13_dp)
        x = r - 2.0_dp*s
        call ldlt_solve_real(n, k, s1, x)
        call check_close(t, trim(label)//': real many-column solve, third column', &
                         bm(3, :), x, 1.0e-13_dp, 1.0e-13_dp)
        zm(1, :) = cmplx(r, s, dp)
        zm(2, :) = cmplx(s, -r, dp)
        call ldlt_solve_cplx_many(n, k, s2, 2, zm)
        call check_close(t, trim(label)//': complex many-column solve (real part)', &
                         real(zm(1, :), dp), real(z, dp), 1.0e-13_dp, 1.0e-13_dp)
        call check_close(t, trim(label)//': complex many-column solve (imaginary part)', &
                         aimag(zm(1, :)), aimag(z), 1.0e-13_dp, 1.0e-13_dp)
        z = cmplx(s, -r, dp)
        call ldlt_solve_cplx(n, k, s2, z)
        call check_close(t, trim(label)//': complex many-column solve, second column', &
                         real(zm(2, :), dp), real(z, dp), 1.0e-13_dp, 1.0e-13_dp)
    end subroutine symmetric_band

    subroutine symmetric_band_refuses_bad_pivots()
        real(dp) :: s1(2, 3)
        complex(dp) :: s2(2, 3)
        logical :: ok
        s1 = 0.0_dp
        s1(1, :) = [1.0_dp, -2.0_dp, 3.0_dp]
        call ldlt_real(3, 1, s1, ok)
        call check_true(t, 'L D L^T refuses a negative pivot', .not. ok)
        s2 = (0.0_dp, 0.0_dp)
        s2(1, :) = [(1.0_dp, 1.0_dp), (1.0_dp, -1.0_dp), (1.0_dp, 1.0_dp)]
        call ldlt_cplx(3, 1, s2, ok)
        call check_true(t, 'complex L D L^T refuses a pivot with a negative imaginary part', &
                        .not. ok)
    end subroutine symmetric_band_refuses_bad_pivots

    !> band_add builds the band storage entry by entry (real and complex);
    !! band_to_dense gives the matrix back exactly, band_mv on the assembly
    !! array is the dense product, and band_solve with several right-hand
    !! sides is the single solves column by column.
    subroutine assembly_helpers(n, kl, ku)
        integer, intent(in) :: n, kl, ku
        real(dp) :: a(n, n), b(n, n), d(n, n), ab(2*kl + ku + 1, n), x(n), y(n), r(n, 2), r0(n, 2)
        complex(dp) :: zab(2*kl + ku + 1, n), zd(n, n), zy(n), zr(n, 2), zx(n)
        type(band_lu_t) :: lu
        type(zband_lu_t) :: zlu
        type(status_t) :: stat
        character(len=64) :: label
        integer :: i, j
        write (label, '(a, 3(i0, 1x))') 'assembly helpers n kl ku: ', n, kl, ku
        a = band_matrix(n, kl, ku, .false.)
        b = band_matrix(n, kl, ku, .false.)
        ab = 0.0_dp
        zab = (0.0_dp, 0.0_dp)
        do j = 1, n
            do i = max(1, j - ku), min(n, j + kl)
                call band_add(ab, kl, ku, i, j, a(i, j))
                call band_add(zab, kl, ku, i, j, cmplx(a(i, j), 0.0_dp, dp))
                call band_add(zab, kl, ku, i, j, cmplx(0.0_dp, b(i, j), dp))
            end do
        end do
        call band_to_dense(ab, kl, ku, d)
        call check_close(t, trim(label)//': real dense copy', d, a, 0.0_dp, 0.0_dp)
        call band_to_dense(zab, kl, ku, zd)
        call check_close(t, trim(label)//': complex dense copy', &
                         reshape([real(zd, dp), aimag(zd)], [2*n*n]), &
                         reshape([a, b], [2*n*n]), 0.0_dp, 0.0_dp)
        x = reshape(normal(n, 1), [n])
        call band_mv(ab, kl, ku, x, y)
        call check_close(t, trim(label)//': real product', y, matmul(a, x), 1.0e-13_dp, &
                         1.0e-13_dp)
        call band_mv(zab, kl, ku, cmplx(x, 0.0_dp, dp), zy)
        call check_close(t, trim(label)//': complex product', aimag(zy), matmul(b, x), &
                         1.0e-13_dp, 1.0e-13_dp)
        lu = band_lu_t(n=n, kl=kl, ku=ku, ab=ab)
        zlu = zband_lu_t(n=n, kl=kl, ku=ku, ab=zab)
        call band_factor(lu, stat)
        call band_factor(zlu, stat)
        call check_true(t, trim(label)//': factored', stat%code == STATUS_OK)
        r0 = normal(n, 2)
        r = r0
        zr = cmplx(r0, 2.0_dp*r0, dp)
        call band_solve(lu, r)
        call band_solve(zlu, zr)
        do j = 1, 2
            y = r0(:, j)
            call band_solve(lu, y)
            call check_close(t, trim(label)//': real several right-hand sides', r(:, j), y, &
                             0.0_dp, 0.0_dp)
            zx = cmplx(r0(:, j), 2.0_dp*r0(:, j), dp)
            call band_solve(zlu, zx)
            call check_close(t, trim(label)//': complex several right-hand sides', &
                             [real(zr(:, j), dp), aimag(zr(:, j))], &
                             [real(zx, dp), aimag(zx)], 0.0_dp, 0.0_dp)
        end do
    end subroutine assembly_helpers

    !> A = L D L^T from a unit lower band L of half-bandwidth k (so A has the
    !! same band) and a D with chosen signs: ldlt_inertia counts the negative
    !! entries of D (Sylvester's law of inertia).
    subroutine inertia(n, k)
        integer, intent(in) :: n, k
        real(dp) :: l(n, n), a(n, n), d(n), s(k + 1, n)
        character(len=64) :: label
        integer :: i, j, negative
        write (label, '(a, 2(i0, 1x))') 'inertia n k: ', n, k
        l = 0.3_dp*normal(n, n)
        d = 1.0_dp + abs(reshape(normal(n, 1), [n]))
        d(2:n:4) = -d(2:n:4)
        do j = 1, n
            do i = 1, n
                if (i < j .or. i - j > k) l(i, j) = 0.0_dp
            end do
            l(j, j) = 1.0_dp
        end do
        a = matmul(l*spread(d, 1, n), transpose(l))
        do j = 1, n
            do i = j, min(n, j + k)
                s(1 + i - j, j) = a(i, j)
            end do
        end do
        call ldlt_inertia(n, k, s, negative)
        call check_true(t, trim(label)//': negative pivots = negative entries of D', &
                        negative == count(d < 0.0_dp))
    end subroutine inertia

end program test_band
