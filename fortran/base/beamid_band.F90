!> Banded linear algebra (issue 11.3): one module for the band LU with
!! partial pivoting (LAPACK general band storage, the algorithm of
!! dgbtf2/dgbtrs written out for the narrow bands of the chain), the L D L^T
!! of symmetric band matrices without pivoting (real, and complex symmetric:
!! no conjugation), band products, multi-right-hand-side solves, the
!! assembly helpers and the inertia count of the FE stability check, real
!! and complex behind generic interfaces (band_factor, band_solve,
!! ldlt_factor, ldlt_solve, band_mv, band_add, band_scatter, band_to_dense).
!! Every routine that exists for both
!! kinds is written once, in beamid_band_generic.inc, and instantiated for
!! real(dp) and complex(dp) by the preprocessor (as fortran-lang/stdlib does
!! with fypp); the kinds differ only in the scalar rules defined below: the
!! pivot size, the accepted L D L^T pivot and the form of the LU update's
!! product (complex: re(u) l + im(u) (i l) with i l stored beside l, which
!! keeps the complex step as fast as hand-written (re, im) code). The
!! specific names (dband_*, zband_*, ldlt_real, ldlt_cplx, ...) stay public
!! for callers that name the kind.
module beamid_band
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_INPUT, ERR_SINGULAR, fmt_int
    implicit none
    private

    public :: band_lu_t, zband_lu_t
    public :: band_factor, band_solve, zband_factor, zband_solve, band_solve_many, &
              zband_solve_many
    public :: ldlt_real, ldlt_cplx, ldlt_solve_real, ldlt_solve_cplx, ldlt_factor, ldlt_solve
    public :: dband_mv, zband_mv, band_mv, kc_mv, ldlt_inertia
    public :: band_add, band_scatter, band_to_dense
    public :: ldlt_solve_real_many, ldlt_solve_cplx_many

    !> Factor a real or complex band matrix (band_lu_t, zband_lu_t).
    interface band_factor
        module procedure dband_factor, zband_factor
    end interface band_factor
    !> Solve with the factors, one right-hand side or several (columns).
    interface band_solve
        module procedure dband_solve, zband_solve, band_solve_many, zband_solve_many
    end interface band_solve
    !> L D L^T of a symmetric band matrix, real or complex symmetric.
    interface ldlt_factor
        module procedure ldlt_real, ldlt_cplx
    end interface ldlt_factor
    !> Solve with the L D L^T factors.
    interface ldlt_solve
        module procedure ldlt_solve_real, ldlt_solve_cplx
    end interface ldlt_solve
    !> y = A x for a real or complex band matrix: (n, kl, ku, ab, x, y) with
    !! explicit shapes, or (ab, kl, ku, x, y) with the order from ab.
    interface band_mv
        module procedure dband_mv, zband_mv, dband_mv_shaped, zband_mv_shaped
    end interface band_mv
    !> A(i, j) += value in band storage.
    interface band_add
        module procedure dband_add, zband_add
    end interface band_add
    !> Add an element matrix into band storage.
    interface band_scatter
        module procedure dband_scatter, zband_scatter
    end interface band_scatter
    !> Dense copy of a band matrix.
    interface band_to_dense
        module procedure dband_to_dense, zband_to_dense
    end interface band_to_dense

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

#define BAND_T real(dp)
#define LU_T band_lu_t
#define WHERE_ 'band_factor'
#define ABS1_(x) abs(x)
#define PIVOT_OK_(d) (d > 0.0_dp)
#define NL_ 1
#define TIMES_I_(x) x
#define MUL_(u, l, il) u*l
#define FACTOR_ dband_factor
#define SOLVE_ dband_solve
#define SOLVE_MANY_ band_solve_many
#define LU_ dband_lu
#define UPDATE_ dband_update
#define LU_SOLVE_ dband_lu_solve
#define LDLT_ ldlt_real
#define LDLT_COLUMN_ ldlt_column_real
#define LDLT_SOLVE_ ldlt_solve_real
#define LDLT_SOLVE_MANY_ ldlt_solve_real_many
#define LDLT_AXPY_ ldlt_axpy_real
#define LDLT_DOT_ ldlt_dot_real
#define MV_ dband_mv
#define MV_SHAPED_ dband_mv_shaped
#define ADD_ dband_add
#define SCATTER_ dband_scatter
#define TO_DENSE_ dband_to_dense
#include "beamid_band_generic.inc"
#define BAND_T complex(dp)
#define LU_T zband_lu_t
#define WHERE_ 'zband_factor'
#define ABS1_(x) (abs(x%re) + abs(x%im))
#define PIVOT_OK_(d) (d%im > 0.0_dp)
#define NL_ 2
#define TIMES_I_(x) cmplx(-x%im, x%re, dp)
#define MUL_(u, l, il) cmplx(u%re*l%re + u%im*il%re, u%re*l%im + u%im*il%im, dp)
#define FACTOR_ zband_factor
#define SOLVE_ zband_solve
#define SOLVE_MANY_ zband_solve_many
#define LU_ zband_lu
#define UPDATE_ zband_update
#define LU_SOLVE_ zband_lu_solve
#define LDLT_ ldlt_cplx
#define LDLT_COLUMN_ ldlt_column_cplx
#define LDLT_SOLVE_ ldlt_solve_cplx
#define LDLT_SOLVE_MANY_ ldlt_solve_cplx_many
#define LDLT_AXPY_ ldlt_axpy_cplx
#define LDLT_DOT_ ldlt_dot_cplx
#define MV_ zband_mv
#define MV_SHAPED_ zband_mv_shaped
#define ADD_ zband_add
#define SCATTER_ zband_scatter
#define TO_DENSE_ zband_to_dense
#include "beamid_band_generic.inc"

    !> Number of negative pivots of the L D L^T without pivoting of a real
    !! symmetric band matrix (lower band as for ldlt_real, overwritten): by
    !! Sylvester's law of inertia its number of negative eigenvalues. A zero
    !! pivot (exactly at a critical point) counts as neither sign and its
    !! column updates nothing.
    pure subroutine ldlt_inertia(n, k, s, negative)
        integer, intent(in) :: n, k
        real(dp), intent(inout) :: s(k + 1, n)
        integer, intent(out) :: negative
        integer :: j
        negative = 0
        do j = 1, n
            if (s(1, j) < 0.0_dp) negative = negative + 1
            if (s(1, j) /= 0.0_dp) call ldlt_column_real(k, min(k, n - j), 1.0_dp/s(1, j), s(1, j))
        end do
    end subroutine ldlt_inertia

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

end module beamid_band
