!> Checked wrappers around the LAPACK routines beamid uses.
!!
!! Reference LAPACK's xerbla STOPs on a bad argument, which would kill a Python
!! host, so every wrapper checks shapes before the call and turns INFO into a
!! beamid status (negative INFO cannot happen after the checks; positive INFO
!! becomes ERR_SINGULAR with the routine's meaning).
module beamid_lapack
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_INPUT, ERR_SINGULAR, fmt_int
    implicit none
    private

    public :: solve_dense, solve_banded, sym_gen_eig, svd_thin, gen_eig

    interface
        subroutine dgesv(n, nrhs, a, lda, ipiv, b, ldb, info)
            import :: dp
            integer, intent(in) :: n, nrhs, lda, ldb
            real(dp), intent(inout) :: a(lda, *), b(ldb, *)
            integer, intent(out) :: ipiv(*), info
        end subroutine dgesv
        subroutine dgbsv(n, kl, ku, nrhs, ab, ldab, ipiv, b, ldb, info)
            import :: dp
            integer, intent(in) :: n, kl, ku, nrhs, ldab, ldb
            real(dp), intent(inout) :: ab(ldab, *), b(ldb, *)
            integer, intent(out) :: ipiv(*), info
        end subroutine dgbsv
        subroutine dsygv(itype, jobz, uplo, n, a, lda, b, ldb, w, work, lwork, info)
            import :: dp
            integer, intent(in) :: itype, n, lda, ldb, lwork
            character(len=1), intent(in) :: jobz, uplo
            real(dp), intent(inout) :: a(lda, *), b(ldb, *)
            real(dp), intent(out) :: w(*), work(*)
            integer, intent(out) :: info
        end subroutine dsygv
        subroutine dgesvd(jobu, jobvt, m, n, a, lda, s, u, ldu, vt, ldvt, work, lwork, info)
            import :: dp
            character(len=1), intent(in) :: jobu, jobvt
            integer, intent(in) :: m, n, lda, ldu, ldvt, lwork
            real(dp), intent(inout) :: a(lda, *)
            real(dp), intent(out) :: s(*), u(ldu, *), vt(ldvt, *), work(*)
            integer, intent(out) :: info
        end subroutine dgesvd
        subroutine dgeev(jobvl, jobvr, n, a, lda, wr, wi, vl, ldvl, vr, ldvr, work, lwork, &
                         info)
            import :: dp
            character(len=1), intent(in) :: jobvl, jobvr
            integer, intent(in) :: n, lda, ldvl, ldvr, lwork
            real(dp), intent(inout) :: a(lda, *)
            real(dp), intent(out) :: wr(*), wi(*), vl(ldvl, *), vr(ldvr, *), work(*)
            integer, intent(out) :: info
        end subroutine dgeev
    end interface

contains

    !> Solve A X = B in place (B becomes X) by LU with partial pivoting (dgesv).
    !! A is overwritten by its factors.
    subroutine solve_dense(a, b, stat)
        real(dp), intent(inout) :: a(:, :)
        real(dp), intent(inout) :: b(:, :)
        type(status_t), intent(inout) :: stat
        integer, allocatable :: ipiv(:)
        integer :: n, info
        n = size(a, 1)
        if (size(a, 2) /= n .or. size(b, 1) /= n) then
            call set_status(stat, ERR_INPUT, 'solve_dense', 'shape mismatch: A is '// &
                            fmt_int(size(a, 1))//'x'//fmt_int(size(a, 2))//', B has '// &
                            fmt_int(size(b, 1))//' rows')
            return
        end if
        if (n == 0 .or. size(b, 2) == 0) return
        allocate (ipiv(n))
        call dgesv(n, size(b, 2), a, n, ipiv, b, n, info)
        if (info > 0) call set_status(stat, ERR_SINGULAR, 'solve_dense', &
                                      'matrix is singular (zero pivot '//fmt_int(info)//')')
    end subroutine solve_dense

    !> Solve a banded system (dgbsv). `ab` is in LAPACK band storage with
    !! 2*kl+ku+1 rows: row kl+ku+1+i-j holds A(i,j). Overwritten by the factors.
    subroutine solve_banded(kl, ku, ab, b, stat)
        integer, intent(in) :: kl, ku
        real(dp), intent(inout) :: ab(:, :)
        real(dp), intent(inout) :: b(:, :)
        type(status_t), intent(inout) :: stat
        integer, allocatable :: ipiv(:)
        integer :: n, info
        n = size(ab, 2)
        if (kl < 0 .or. ku < 0 .or. size(ab, 1) /= 2*kl + ku + 1 .or. size(b, 1) /= n) then
            call set_status(stat, ERR_INPUT, 'solve_banded', 'band storage is '// &
                            fmt_int(size(ab, 1))//'x'//fmt_int(n)//' for kl='//fmt_int(kl)// &
                            ', ku='//fmt_int(ku)//', rhs rows '//fmt_int(size(b, 1)))
            return
        end if
        if (n == 0 .or. size(b, 2) == 0) return
        allocate (ipiv(n))
        call dgbsv(n, kl, ku, size(b, 2), ab, size(ab, 1), ipiv, b, n, info)
        if (info > 0) call set_status(stat, ERR_SINGULAR, 'solve_banded', &
                                      'matrix is singular (zero pivot '//fmt_int(info)//')')
    end subroutine solve_banded

    !> Generalized symmetric-definite eigenproblem K v = w M v (dsygv, itype 1).
    !! On return `k` holds the M-normalized eigenvectors (columns), `w` ascending.
    subroutine sym_gen_eig(k, m, w, stat)
        real(dp), intent(inout) :: k(:, :), m(:, :)
        real(dp), intent(out) :: w(:)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: work(:)
        real(dp) :: query(1)
        integer :: n, info
        n = size(k, 1)
        if (size(k, 2) /= n .or. any(shape(m) /= [n, n]) .or. size(w) /= n) then
            call set_status(stat, ERR_INPUT, 'sym_gen_eig', 'shape mismatch for n = '// &
                            fmt_int(n))
            return
        end if
        if (n == 0) return
        call dsygv(1, 'V', 'U', n, k, n, m, n, w, query, -1, info)
        allocate (work(max(1, int(query(1)))))
        call dsygv(1, 'V', 'U', n, k, n, m, n, w, work, size(work), info)
        if (info > n) then
            call set_status(stat, ERR_SINGULAR, 'sym_gen_eig', 'mass matrix is not '// &
                            'positive definite (leading minor '//fmt_int(info - n)//')')
        else if (info > 0) then
            call set_status(stat, ERR_SINGULAR, 'sym_gen_eig', 'eigenvalue iteration '// &
                            'did not converge ('//fmt_int(info)//' off-diagonals)')
        end if
    end subroutine sym_gen_eig

    !> Thin SVD A = U diag(s) V^T of an m x n matrix (dgesvd). `a` is destroyed.
    !! u is m x min(m,n), vt is min(m,n) x n, s descending.
    subroutine svd_thin(a, s, u, vt, stat)
        real(dp), intent(inout) :: a(:, :)
        real(dp), intent(out) :: s(:), u(:, :), vt(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: work(:)
        real(dp) :: query(1)
        integer :: m, n, r, info
        m = size(a, 1)
        n = size(a, 2)
        r = min(m, n)
        if (size(s) /= r .or. any(shape(u) /= [m, r]) .or. any(shape(vt) /= [r, n])) then
            call set_status(stat, ERR_INPUT, 'svd_thin', 'output shapes do not match a '// &
                            fmt_int(m)//'x'//fmt_int(n)//' matrix')
            return
        end if
        if (r == 0) return
        call dgesvd('S', 'S', m, n, a, m, s, u, m, vt, r, query, -1, info)
        allocate (work(max(1, int(query(1)))))
        call dgesvd('S', 'S', m, n, a, m, s, u, m, vt, r, work, size(work), info)
        if (info > 0) call set_status(stat, ERR_SINGULAR, 'svd_thin', 'SVD did not '// &
                                      'converge ('//fmt_int(info)//' superdiagonals)')
    end subroutine svd_thin

    !> Eigenvalues wr + i wi and right eigenvectors of a general real square
    !! matrix (dgeev). `a` is destroyed. A complex pair (wi(j) > 0, wi(j+1) =
    !! -wi(j)) has the eigenvector vr(:, j) + i vr(:, j+1) for eigenvalue j
    !! (LAPACK's packing).
    subroutine gen_eig(a, wr, wi, vr, stat)
        real(dp), intent(inout) :: a(:, :)
        real(dp), intent(out) :: wr(:), wi(:), vr(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: work(:)
        real(dp) :: query(1), vl(1, 1)
        integer :: n, info
        n = size(a, 1)
        if (size(a, 2) /= n .or. size(wr) /= n .or. size(wi) /= n .or. &
            any(shape(vr) /= [n, n])) then
            call set_status(stat, ERR_INPUT, 'gen_eig', 'shape mismatch for n = '// &
                            fmt_int(n))
            return
        end if
        if (n == 0) return
        call dgeev('N', 'V', n, a, n, wr, wi, vl, 1, vr, n, query, -1, info)
        allocate (work(max(1, int(query(1)))))
        call dgeev('N', 'V', n, a, n, wr, wi, vl, 1, vr, n, work, size(work), info)
        if (info > 0) call set_status(stat, ERR_SINGULAR, 'gen_eig', 'QR iteration did '// &
                                      'not converge ('//fmt_int(info)//' eigenvalues left)')
    end subroutine gen_eig
end module beamid_lapack
