!> Banded linear algebra of the dynamics (issue 11.3): one module for the
!! band LU with partial pivoting (LAPACK general band storage, the algorithm
!! of dgbtf2/dgbtrs written out for the narrow bands of the chain), the
!! L D L^T of symmetric band matrices without pivoting (real, and complex
!! symmetric: no conjugation), band products and multi-right-hand-side
!! solves, real and complex behind generic interfaces (band_factor,
!! band_solve, ldlt_factor, ldlt_solve, band_mv). The routines that are the
!! same for both kinds (factor and solve drivers, the band LU solve, the band
!! product) are written once, in beamid_band_generic.inc, and instantiated
!! for real(dp) and complex(dp) by the preprocessor. The LU factorization's
!! trailing update and the L D L^T kernels keep separate real and complex
!! bodies: the complex ones are written on (re, im) pairs and test a
!! different pivot (the imaginary part), and the complex step's speed rests
!! on them; the pairs sit side by side here.
module beamid_band
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_INPUT, ERR_SINGULAR, fmt_int
    implicit none
    private

    public :: band_lu_t, zband_lu_t
    public :: band_factor, band_solve, zband_factor, zband_solve, band_solve_many
    public :: ldlt_real, ldlt_cplx, ldlt_solve_real, ldlt_solve_cplx, ldlt_factor, ldlt_solve
    public :: dband_mv, zband_mv, band_mv, kc_mv
    public :: ldlt_solve_real_many, ldlt_solve_cplx_many

    !> Factor a real or complex band matrix (band_lu_t, zband_lu_t).
    interface band_factor
        module procedure dband_factor, zband_factor
    end interface band_factor
    !> Solve with the factors, one right-hand side or several (columns).
    interface band_solve
        module procedure dband_solve, zband_solve, band_solve_many
    end interface band_solve
    !> L D L^T of a symmetric band matrix, real or complex symmetric.
    interface ldlt_factor
        module procedure ldlt_real, ldlt_cplx
    end interface ldlt_factor
    !> Solve with the L D L^T factors.
    interface ldlt_solve
        module procedure ldlt_solve_real, ldlt_solve_cplx
    end interface ldlt_solve
    !> y = A x for a real or complex band matrix.
    interface band_mv
        module procedure dband_mv, zband_mv
    end interface band_mv

    !> A factorized real band matrix (dgbtrf).
    type :: band_lu_t
        integer :: n = 0, kl = 0, ku = 0
        real(dp), allocatable :: ab(:, :)
        integer, allocatable :: ipiv(:)
    end type band_lu_t

    !> A factorized complex band matrix (zgbtrf).
    type :: zband_lu_t
        integer :: n = 0, kl = 0, ku = 0
        complex(dp), allocatable :: ab(:, :)
        integer, allocatable :: ipiv(:)
    end type zband_lu_t

contains

    ! The kind-generic band routines, written once in beamid_band_generic.inc
    ! and instantiated for real and complex by the preprocessor.
#define BAND_T real(dp)
#define LU_T band_lu_t
#define FACTOR_ dband_factor
#define SOLVE_ dband_solve
#define LU_ dband_lu
#define LU_SOLVE_ dband_lu_solve
#define MV_ dband_mv
#define WHERE_ 'band_factor'
#include "beamid_band_generic.inc"
#undef BAND_T
#undef LU_T
#undef FACTOR_
#undef SOLVE_
#undef LU_
#undef LU_SOLVE_
#undef MV_
#undef WHERE_
#define BAND_T complex(dp)
#define LU_T zband_lu_t
#define FACTOR_ zband_factor
#define SOLVE_ zband_solve
#define LU_ zband_lu
#define LU_SOLVE_ zband_lu_solve
#define MV_ zband_mv
#define WHERE_ 'zband_factor'
#include "beamid_band_generic.inc"





    !> LU factorization with partial pivoting of a band matrix in LAPACK
    !! general band storage (the algorithm of dgbtf2, written out: for the
    !! narrow bands of the chain, kl = ku = 7, the BLAS calls per column of
    !! the reference dgbtf2 cost more than the arithmetic). info > 0: zero
    !! pivot in column info (the factorization is completed).
    !!
    !! Column j: pick the pivot, scale the multipliers, then one pass over the
    !! columns j+1..ju (dband_update) that swaps the pivot row and applies the
    !! rank-1 update, both within each column: no strided swap loop.
    pure subroutine dband_lu(n, kl, ku, ab, ipiv, info)
        integer, intent(in) :: n, kl, ku
        real(dp), intent(inout) :: ab(2*kl + ku + 1, n)
        integer, intent(out) :: ipiv(n), info
        real(dp) :: piv, mag, tmp, rec
        integer :: kv, j, i, jp, ju, km, p
        info = 0
        kv = ku + kl
        ! fill-in rows above the band start at zero
        ab(1:kl, :) = 0.0_dp
        ju = 1
        do j = 1, n
            km = min(kl, n - j)
            ! pivot: the first largest |a(j+i, j)|, i = 0..km, at ab(kv + 1 + i, j)
            p = kv + 1
            piv = abs(ab(p, j))
            do i = kv + 2, kv + 1 + km
                mag = abs(ab(i, j))
                if (mag > piv) then
                    piv = mag
                    p = i
                end if
            end do
            jp = p - kv - 1
            ipiv(j) = j + jp
            if (ab(p, j) == 0.0_dp) then
                if (info == 0) info = j
                cycle
            end if
            ju = max(ju, min(j + ku + jp, n))
            if (jp /= 0) then
                tmp = ab(kv + 1, j)
                ab(kv + 1, j) = ab(p, j)
                ab(p, j) = tmp
            end if
            if (km == 0) cycle
            rec = 1.0_dp/ab(kv + 1, j)
            do i = kv + 2, kv + 1 + km
                ab(i, j) = ab(i, j)*rec
            end do
            ! a(j, j+1) sits at ab(kv, j+1); column j+c of the trailing block
            ! starts 2 kl + ku elements after column j+c-1 (kl >= 1 here)
            if (ju > j) call dband_update(km, ju - j, jp, 2*kl + ku, &
                                          ab(kv + 2:kv + 1 + km, j), ab(kv, j + 1))
        end do
    end subroutine dband_lu

    !> Trailing update of one step of dband_lu. w is the band storage from
    !! a(j, j+1) on, seen with leading dimension ldw = 2 kl + ku (one less
    !! than the band's), so that w(o), o = (c-1) ldw + 1, is a(j, j+c) and
    !! w(o+i) is a(j+i, j+c): each column of the block is contiguous. Per
    !! column: swap rows j and j+jp, then a(j+i, j+c) -= a(j, j+c) l(i).
    pure subroutine dband_update(m, nc, jp, ldw, l, w)
        integer, intent(in) :: m, nc, jp, ldw
        real(dp), intent(in) :: l(m)
        real(dp), intent(inout) :: w(ldw*(nc - 1) + m + 1)
        real(dp) :: u
        integer :: c, i, o
        do c = 1, nc
            o = (c - 1)*ldw + 1
            u = w(o + jp)
            if (jp /= 0) then
                w(o + jp) = w(o)
                w(o) = u
            end if
            if (u /= 0.0_dp) then
                do i = 1, m
                    w(o + i) = w(o + i) - u*l(i)
                end do
            end if
        end do
    end subroutine dband_update


    !> Complex counterpart of dband_lu (pivot by |re| + |im|, as izamax).
    pure subroutine zband_lu(n, kl, ku, ab, ipiv, info)
        integer, intent(in) :: n, kl, ku
        complex(dp), intent(inout) :: ab(2*kl + ku + 1, n)
        integer, intent(out) :: ipiv(n), info
        complex(dp) :: il(kl)   ! i times the multipliers (see zband_update)
        real(dp) :: piv, mag
        complex(dp) :: tmp, rec
        integer :: kv, j, i, jp, ju, km, p
        info = 0
        kv = ku + kl
        ab(1:kl, :) = (0.0_dp, 0.0_dp)
        ju = 1
        do j = 1, n
            km = min(kl, n - j)
            p = kv + 1
            piv = abs(ab(p, j)%re) + abs(ab(p, j)%im)
            do i = kv + 2, kv + 1 + km
                mag = abs(ab(i, j)%re) + abs(ab(i, j)%im)
                if (mag > piv) then
                    piv = mag
                    p = i
                end if
            end do
            jp = p - kv - 1
            ipiv(j) = j + jp
            if (piv == 0.0_dp) then
                if (info == 0) info = j
                cycle
            end if
            ju = max(ju, min(j + ku + jp, n))
            if (jp /= 0) then
                tmp = ab(kv + 1, j)
                ab(kv + 1, j) = ab(p, j)
                ab(p, j) = tmp
            end if
            if (km == 0) cycle
            rec = 1.0_dp/ab(kv + 1, j)
            do i = 1, km
                ab(kv + 1 + i, j) = ab(kv + 1 + i, j)*rec
                il(i) = cmplx(-ab(kv + 1 + i, j)%im, ab(kv + 1 + i, j)%re, dp)
            end do
            if (ju > j) call zband_update(km, ju - j, jp, 2*kl + ku, &
                                          ab(kv + 2:kv + 1 + km, j), il, ab(kv, j + 1))
        end do
    end subroutine zband_lu

    !> Complex counterpart of dband_update. The product u l(i) is formed as
    !! re(u) l(i) + im(u) (i l(i)) with i l(i) = (-im l, re l) precomputed:
    !! the same roundings as complex multiplication, but two multiplies of
    !! (re, im) pairs and one add, with no shuffles in the loop.
    pure subroutine zband_update(m, nc, jp, ldw, l, il, w)
        integer, intent(in) :: m, nc, jp, ldw
        complex(dp), intent(in) :: l(m), il(m)
        complex(dp), intent(inout) :: w(ldw*(nc - 1) + m + 1)
        complex(dp) :: u
        real(dp) :: ur, ui
        integer :: c, i, o
        do c = 1, nc
            o = (c - 1)*ldw + 1
            u = w(o + jp)
            if (jp /= 0) then
                w(o + jp) = w(o)
                w(o) = u
            end if
            if (u /= (0.0_dp, 0.0_dp)) then
                ur = u%re
                ui = u%im
                do i = 1, m
                    w(o + i) = w(o + i) - cmplx(ur*l(i)%re + ui*il(i)%re, &
                                                ur*l(i)%im + ui*il(i)%im, dp)
                end do
            end if
        end do
    end subroutine zband_update


    !> L D L^T of a symmetric band matrix of half-bandwidth k, lower band
    !! s(1 + i - j, j) = A(i, j), without pivoting: D on row 1, L below.
    !! False (s then unusable) at the first pivot that is not positive.
    pure subroutine ldlt_real(n, k, s, ok)
        integer, intent(in) :: n, k
        logical, intent(out) :: ok
        real(dp), intent(inout) :: s(k + 1, n)
        integer :: j, c, r, m, j0
        real(dp) :: d, dinv, vc
        integer, parameter :: K7 = 7
        ok = .false.
        j0 = 1
        if (k == K7) then
            do j = 1, n - K7
                d = s(1, j)
                if (.not. (d > 0.0_dp)) return
                dinv = 1.0_dp/d
                s(2:K7 + 1, j) = s(2:K7 + 1, j)*dinv
                do c = 1, K7
                    vc = s(1 + c, j)*d
                    do r = c, K7
                        s(1 + r - c, j + c) = s(1 + r - c, j + c) - s(1 + r, j)*vc
                    end do
                end do
            end do
            j0 = max(1, n - K7 + 1)
        end if
        do j = j0, n
            d = s(1, j)
            if (.not. (d > 0.0_dp)) return
            dinv = 1.0_dp/d
            ! the scaled column first: l_r = a_r / d; then the trailing update
            ! A(r, c) -= l_r d l_c over the lower triangle
            m = min(k, n - j)
            do r = 2, m + 1
                s(r, j) = s(r, j)*dinv
            end do
            do c = 1, m
                vc = s(1 + c, j)*d
                do r = c, m
                    s(1 + r - c, j + c) = s(1 + r - c, j + c) - s(1 + r, j)*vc
                end do
            end do
        end do
        ok = .true.
    end subroutine ldlt_real

    !> Complex symmetric counterpart of ldlt_real; false at the first pivot
    !! whose imaginary part is not positive.
    pure subroutine ldlt_cplx(n, k, s, ok)
        integer, intent(in) :: n, k
        logical, intent(out) :: ok
        complex(dp), intent(inout) :: s(k + 1, n)
        integer :: j, c, r, m, j0
        complex(dp) :: d, dinv
        real(dp) :: vr, vi, sr, si
        integer, parameter :: K7 = 7
        ok = .false.
        j0 = 1
        if (k == K7) then
            do j = 1, n - K7
                d = s(1, j)
                if (.not. (d%im > 0.0_dp)) return
                dinv = 1.0_dp/d
                do c = 1, K7
                    vr = s(1 + c, j)%re*dinv%re - s(1 + c, j)%im*dinv%im
                    vi = s(1 + c, j)%re*dinv%im + s(1 + c, j)%im*dinv%re
                    do r = c, K7
                        sr = s(1 + r, j)%re
                        si = s(1 + r, j)%im
                        s(1 + r - c, j + c)%re = s(1 + r - c, j + c)%re - (sr*vr - si*vi)
                        s(1 + r - c, j + c)%im = s(1 + r - c, j + c)%im - (sr*vi + si*vr)
                    end do
                end do
                s(2:K7 + 1, j) = s(2:K7 + 1, j)*dinv
            end do
            j0 = max(1, n - K7 + 1)
        end if
        do j = j0, n
            d = s(1, j)
            if (.not. (d%im > 0.0_dp)) return
            dinv = 1.0_dp/d
            m = min(k, n - j)
            do c = 1, m
                vr = s(1 + c, j)%re*dinv%re - s(1 + c, j)%im*dinv%im
                vi = s(1 + c, j)%re*dinv%im + s(1 + c, j)%im*dinv%re
                do r = c, m
                    sr = s(1 + r, j)%re
                    si = s(1 + r, j)%im
                    s(1 + r - c, j + c)%re = s(1 + r - c, j + c)%re - (sr*vr - si*vi)
                    s(1 + r - c, j + c)%im = s(1 + r - c, j + c)%im - (sr*vi + si*vr)
                end do
            end do
            do r = 2, m + 1
                s(r, j) = s(r, j)*dinv
            end do
        end do
        ok = .true.
    end subroutine ldlt_cplx

    !> Solve L D L^T x = b (ldlt_real factors), b overwritten.
    pure subroutine ldlt_solve_real(n, k, s, b)
        integer, intent(in) :: n, k
        real(dp), intent(in) :: s(k + 1, n)
        real(dp), intent(inout) :: b(n)
        integer, parameter :: K7 = 7
        integer :: i, j, m, j0
        real(dp) :: bj, acc
        ! forward: L y = b (columns j <= n - k have the full k entries; with
        ! k = 7, the rigid chain's, the trip count is a constant)
        j0 = 1
        if (k == K7) then
            do j = 1, n - K7
                bj = b(j)
                b(j + 1:j + K7) = b(j + 1:j + K7) - bj*s(2:K7 + 1, j)
            end do
            j0 = max(1, n - K7 + 1)
        end if
        do j = j0, n
            m = min(k, n - j)
            bj = b(j)
            do i = 1, m
                b(j + i) = b(j + i) - bj*s(1 + i, j)
            end do
        end do
        ! backward: D L^T x = y (the last k rows by the general loop)
        j0 = 0
        if (k == K7) j0 = max(0, n - K7)
        do j = n, j0 + 1, -1
            m = min(k, n - j)
            acc = 0.0_dp
            do i = 1, m
                acc = acc + s(1 + i, j)*b(j + i)
            end do
            b(j) = b(j)/s(1, j) - acc
        end do
        if (k == K7) then
            do j = n - K7, 1, -1
                b(j) = b(j)/s(1, j) - sum(s(2:K7 + 1, j)*b(j + 1:j + K7))
            end do
        end if
    end subroutine ldlt_solve_real

    !> Solve with the ldlt_cplx factors (no conjugation), b overwritten.
    pure subroutine ldlt_solve_cplx(n, k, s, b)
        integer, intent(in) :: n, k
        complex(dp), intent(in) :: s(k + 1, n)
        complex(dp), intent(inout) :: b(n)
        integer, parameter :: K7 = 7
        integer :: i, j, m, j0
        real(dp) :: br, bi, sr, si
        j0 = 1
        if (k == K7) then
            do j = 1, n - K7
                br = b(j)%re
                bi = b(j)%im
                do i = 1, K7
                    sr = s(1 + i, j)%re
                    si = s(1 + i, j)%im
                    b(j + i)%re = b(j + i)%re - (br*sr - bi*si)
                    b(j + i)%im = b(j + i)%im - (br*si + bi*sr)
                end do
            end do
            j0 = max(1, n - K7 + 1)
        end if
        do j = j0, n
            m = min(k, n - j)
            br = b(j)%re
            bi = b(j)%im
            do i = 1, m
                sr = s(1 + i, j)%re
                si = s(1 + i, j)%im
                b(j + i)%re = b(j + i)%re - (br*sr - bi*si)
                b(j + i)%im = b(j + i)%im - (br*si + bi*sr)
            end do
        end do
        j0 = 0
        if (k == K7) j0 = max(0, n - K7)
        do j = n, j0 + 1, -1
            m = min(k, n - j)
            br = 0.0_dp
            bi = 0.0_dp
            do i = 1, m
                sr = s(1 + i, j)%re
                si = s(1 + i, j)%im
                br = br + (sr*b(j + i)%re - si*b(j + i)%im)
                bi = bi + (sr*b(j + i)%im + si*b(j + i)%re)
            end do
            b(j) = b(j)/s(1, j) - cmplx(br, bi, dp)
        end do
        if (k == K7) then
            do j = n - K7, 1, -1
                br = 0.0_dp
                bi = 0.0_dp
                do i = 1, K7
                    sr = s(1 + i, j)%re
                    si = s(1 + i, j)%im
                    br = br + (sr*b(j + i)%re - si*b(j + i)%im)
                    bi = bi + (sr*b(j + i)%im + si*b(j + i)%re)
                end do
                b(j) = b(j)/s(1, j) - cmplx(br, bi, dp)
            end do
        end if
    end subroutine ldlt_solve_cplx



    !> y = K x + C v for two band matrices of the same shape (one pass).
    pure subroutine kc_mv(n, kl, ku, kb, cb, x, v, y)
        integer, intent(in) :: n, kl, ku
        real(dp), intent(in) :: kb(2*kl + ku + 1, n), cb(2*kl + ku + 1, n), x(n), v(n)
        real(dp), intent(out) :: y(n)
        integer :: j, i1, i2, k
        real(dp) :: xj, vj
        y = 0.0_dp
        k = kl + ku + 1
        do j = 1, n
            i1 = max(1, j - ku)
            i2 = min(n, j + kl)
            xj = x(j)
            vj = v(j)
            y(i1:i2) = y(i1:i2) + xj*kb(k + i1 - j:k + i2 - j, j) + vj*cb(k + i1 - j:k + i2 - j, j)
        end do
    end subroutine kc_mv

    !> Solve with a factorized real band matrix for the columns of b (several
    !! right-hand sides, e.g. one per sensitivity parameter).
    subroutine band_solve_many(lu, b)
        type(band_lu_t), intent(in) :: lu
        real(dp), intent(inout) :: b(:, :)
        integer :: j
        if (lu%n == 0) return
        do j = 1, size(b, 2)
            call dband_lu_solve(lu%n, lu%kl, lu%ku, lu%ab, lu%ipiv, b(:, j))
        end do
    end subroutine band_solve_many

    !> ldlt_solve_real for nc right-hand sides at once, stored as the rows of
    !! b(nc, n) (the inner loops run over the right-hand sides, contiguous):
    !! the multi-parameter sensitivity solves of the implicit integrator.
    pure subroutine ldlt_solve_real_many(n, k, s, nc, b)
        integer, intent(in) :: n, k, nc
        real(dp), intent(in) :: s(k + 1, n)
        real(dp), intent(inout) :: b(nc, n)
        real(dp) :: acc(nc)
        integer :: i, j, m
        do j = 1, n
            m = min(k, n - j)
            do i = 1, m
                b(:, j + i) = b(:, j + i) - s(1 + i, j)*b(:, j)
            end do
        end do
        do j = n, 1, -1
            m = min(k, n - j)
            acc = 0.0_dp
            do i = 1, m
                acc = acc + s(1 + i, j)*b(:, j + i)
            end do
            b(:, j) = b(:, j)/s(1, j) - acc
        end do
    end subroutine ldlt_solve_real_many

    !> Complex counterpart of ldlt_solve_real_many (the ldlt_cplx factors, no
    !! conjugation).
    pure subroutine ldlt_solve_cplx_many(n, k, s, nc, b)
        integer, intent(in) :: n, k, nc
        complex(dp), intent(in) :: s(k + 1, n)
        complex(dp), intent(inout) :: b(nc, n)
        complex(dp) :: acc(nc)
        integer :: i, j, m
        do j = 1, n
            m = min(k, n - j)
            do i = 1, m
                b(:, j + i) = b(:, j + i) - s(1 + i, j)*b(:, j)
            end do
        end do
        do j = n, 1, -1
            m = min(k, n - j)
            acc = (0.0_dp, 0.0_dp)
            do i = 1, m
                acc = acc + s(1 + i, j)*b(:, j + i)
            end do
            b(:, j) = b(:, j)/s(1, j) - acc
        end do
    end subroutine ldlt_solve_cplx_many

end module beamid_band
