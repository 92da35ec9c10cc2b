!> Static equilibrium of the finite element chain: Newton's method on
!! b(q) = NLT(q) - Q(q) = 0 (Eq. 84-85) with load stepping, pseudo-arc-length
!! path following past limit points, and the linear buckling load.
module beamid_fe_static
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_INPUT, ERR_NO_CONVERGENCE, &
                             ERR_NUMERIC, fmt_int, fmt_real, set_alloc_error
    use beamid_lapack, only: solve_banded, sym_gen_eig, solve_dense
    use beamid_fe_assembly, only: fe_mesh_t, fe_check_dense, fe_load_t, fe_band_rows, &
                                  fe_work_t, fe_work_init, fe_residual, fe_tip_load, &
                                  fe_stiffness_linear, DOF_W, DOF_U, fe_wire_tip, &
                                  fe_wire_force, fe_wire_jacobian, fe_band_to_dense, &
                                  FE_MOMENT_EXACT
    use beamid_band, only: band_scatter, band_to_dense, ldlt_inertia
    use beamid_fe_element, only: FE_NDOF, FE_W, FE_U, fe_hermite
    implicit none
    private

    public :: fe_newton_opts_t, fe_solve_info_t
    public :: fe_residual, fe_newton, fe_solve_static, fe_path, fe_buckling_load
    public :: fe_solve_wire, fe_wire_bordered

    !> Controls of the Newton iteration and of the load stepping.
    type :: fe_newton_opts_t
        real(dp) :: tol = 1.0e-11_dp    !< converged when |dq|_inf <= tol (1 + |q|_inf)
        integer :: max_iter = 40        !< Newton iterations per load step
        integer :: nsteps = 4           !< initial number of equal load steps
        integer :: max_bisect = 20      !< step halvings allowed in total
    end type fe_newton_opts_t

    !> What a static solve did.
    type :: fe_solve_info_t
        integer :: iterations = 0      !< Newton iterations over all steps
        integer :: steps = 0           !< accepted load steps
        real(dp) :: residual = 0.0_dp  !< final |NLT - Q|_inf
        !> Negative eigenvalues of the tangent at the equilibrium (its
        !! symmetric part; fe_negative_eigenvalues): 0 stable, >= 1 unstable
        !! (a compressive load past the buckling load on the straight branch).
        integer :: negative = 0
    end type fe_solve_info_t

    !> Largest change of the slopes (w', u') allowed in one Newton step.
    real(dp), parameter :: MAX_TURN = 0.5_dp

contains

    !> Largest change of a slope unknown (w' or u') in the step dq.
    pure real(dp) function max_slope_change(mesh, dq) result(turn)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: dq(:)
        integer :: k, comp
        turn = 0.0_dp
        do k = 1, mesh%nfree
            comp = mesh%free_comp(k)
            if (comp /= DOF_W .and. comp /= DOF_U) turn = max(turn, abs(dq(k)))
        end do
    end function max_slope_change

    !> Scaled load: `load` with its force and moment times `lam`.
    pure function scaled(load, lam) result(out)
        type(fe_load_t), intent(in) :: load
        real(dp), intent(in) :: lam
        type(fe_load_t) :: out
        out = fe_load_t(lam*load%fx, lam*load%fy, lam*load%moment, load%moment_form)
    end function scaled

    !> Sum of two loads (the moment form of `a` is kept).
    pure function added(a, b) result(out)
        type(fe_load_t), intent(in) :: a, b
        type(fe_load_t) :: out
        out = fe_load_t(a%fx + b%fx, a%fy + b%fy, a%moment + b%moment, a%moment_form)
    end function added

    !> Newton's method (Eq. 85) at a fixed load from the starting shape q.
    !! `work`: from fe_work_init(mesh), shared by the calls of one solve.
    subroutine fe_newton(mesh, load, q, opts, iterations, residual, stat, work)
        type(fe_mesh_t), intent(in) :: mesh
        type(fe_load_t), intent(in) :: load
        real(dp), intent(inout) :: q(:)
        type(fe_newton_opts_t), intent(in) :: opts
        integer, intent(out) :: iterations
        real(dp), intent(out) :: residual
        type(status_t), intent(inout) :: stat
        type(fe_work_t), intent(inout) :: work
        character(len=*), parameter :: where = 'fe_newton'
        real(dp), allocatable :: r(:), jb(:, :), dq(:, :)
        real(dp) :: step, turn
        integer :: it
        allocate (r(mesh%nfree), jb(fe_band_rows(mesh), mesh%nfree), dq(mesh%nfree, 1))
        iterations = 0
        step = huge(1.0_dp)
        do it = 1, opts%max_iter
            iterations = it
            call fe_residual(mesh, load, q, r, jb, work)
            dq(:, 1) = -r
            call solve_banded(mesh%kl, mesh%ku, jb, dq, stat)
            if (stat%code /= 0) return
            ! step-length control: no node may turn by more than MAX_TURN in one step
            ! (keeps Newton from being thrown across the slope range by a poor start;
            ! inactive near a solution, so the quadratic convergence is kept)
            turn = max_slope_change(mesh, dq(:, 1))
            if (turn > MAX_TURN) dq(:, 1) = dq(:, 1)*(MAX_TURN/turn)
            q = q + dq(:, 1)
            step = maxval(abs(dq(:, 1)))
            if (.not. ieee_is_finite(step) .or. step > 1.0e6_dp) then
                call set_status(stat, ERR_NUMERIC, where, 'Newton step became '// &
                                fmt_real(step)//' at iteration '//fmt_int(it))
                return
            end if
            if (step <= opts%tol*(1.0_dp + maxval(abs(q)))) then
                call fe_residual(mesh, load, q, r, work=work)
                residual = maxval(abs(r))
                return
            end if
        end do
        call fe_residual(mesh, load, q, r, work=work)
        residual = maxval(abs(r))
        call set_status(stat, ERR_NO_CONVERGENCE, where, 'no convergence in '// &
                        fmt_int(opts%max_iter)//' iterations: last step '// &
                        fmt_real(step)//', residual '//fmt_real(residual)// &
                        ', tolerance '//fmt_real(opts%tol))
    end subroutine fe_newton

    !> Static equilibrium under `load`. With from_guess, Newton starts from the
    !! shape in q at the full load (this selects among several equilibria, e.g.
    !! above the buckling load, Figure 15). Otherwise the load is applied in
    !! steps from the straight chain, each started from a secant prediction,
    !! halving a step that fails to converge.
    subroutine fe_solve_static(mesh, load, q, from_guess, opts, info, stat)
        type(fe_mesh_t), intent(in) :: mesh
        type(fe_load_t), intent(in) :: load
        real(dp), intent(inout) :: q(:)
        logical, intent(in) :: from_guess
        type(fe_newton_opts_t), intent(in) :: opts
        type(fe_solve_info_t), intent(out) :: info
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'fe_solve_static'
        real(dp), allocatable :: q_old(:), q_prev(:), q_try(:)
        real(dp) :: lam, dlam, dlam_max, dlam_prev, resid
        integer :: its, nbisect
        type(status_t) :: inner
        type(fe_work_t) :: work

        if (size(q) /= mesh%nfree) then
            call set_status(stat, ERR_INPUT, where, 'q has '//fmt_int(size(q))// &
                            ' entries, expected '//fmt_int(mesh%nfree))
            return
        end if
        if (opts%nsteps < 1 .or. opts%max_iter < 1 .or. .not. (opts%tol > 0.0_dp)) then
            call set_status(stat, ERR_INPUT, where, 'nsteps = '//fmt_int(opts%nsteps)// &
                            ', max_iter = '//fmt_int(opts%max_iter)//', tol = '// &
                            fmt_real(opts%tol)//': expected positive values')
            return
        end if
        if (.not. (ieee_is_finite(load%fx) .and. ieee_is_finite(load%fy) .and. &
                   ieee_is_finite(load%moment))) then
            call set_status(stat, ERR_INPUT, where, 'tip load is not finite')
            return
        end if
        call fe_work_init(mesh, work)
        if (from_guess) then
            if (.not. all(ieee_is_finite(q))) then
                call set_status(stat, ERR_INPUT, where, 'starting shape is not finite')
                return
            end if
            call fe_newton(mesh, load, q, opts, info%iterations, info%residual, stat, work)
            info%steps = 1
            if (stat%code == 0) info%negative = fe_negative_eigenvalues(mesh, load, q)
            return
        end if

        q = 0.0_dp
        allocate (q_old(mesh%nfree), q_prev(mesh%nfree), q_try(mesh%nfree))
        q_prev = q
        lam = 0.0_dp
        dlam_max = 1.0_dp/real(opts%nsteps, dp)
        dlam = dlam_max
        dlam_prev = 0.0_dp
        nbisect = 0
        do while (lam < 1.0_dp)
            dlam = min(dlam, 1.0_dp - lam)
            q_try = q
            ! secant predictor along the last accepted step
            if (dlam_prev > 0.0_dp) q_try = q + (q - q_prev)*(dlam/dlam_prev)
            inner = status_t()
            call fe_newton(mesh, scaled(load, lam + dlam), q_try, opts, its, resid, inner, work)
            info%iterations = info%iterations + its
            if (inner%code /= 0) then
                nbisect = nbisect + 1
                if (nbisect > opts%max_bisect) then
                    call set_status(stat, ERR_NO_CONVERGENCE, where, 'load step '// &
                                    fmt_real(dlam)//' from load factor '//fmt_real(lam)// &
                                    ' failed after '//fmt_int(opts%max_bisect)// &
                                    ' halvings; last: '//trim(inner%message))
                    return
                end if
                dlam = 0.5_dp*dlam
                cycle
            end if
            q_prev = q
            q = q_try
            lam = lam + dlam
            if (1.0_dp - lam < 1.0e-14_dp) lam = 1.0_dp
            dlam_prev = dlam
            info%steps = info%steps + 1
            info%residual = resid
            if (its <= 4) dlam = min(2.0_dp*dlam, dlam_max)
        end do
        info%negative = fe_negative_eigenvalues(mesh, load, q)
    end subroutine fe_solve_static

    !> Number of negative eigenvalues of the tangent d(NLT - Q)/dq at q (its
    !! symmetric part, exact for the conservative fixed-direction tip force):
    !! Sylvester's law of inertia on the band L D L^T factorization without
    !! pivoting (beamid_band ldlt_inertia), O(n b^2).
    pure integer function fe_negative_eigenvalues(mesh, load, q) result(negative)
        type(fe_mesh_t), intent(in) :: mesh
        type(fe_load_t), intent(in) :: load
        real(dp), intent(in) :: q(:)
        real(dp), allocatable :: r(:), jb(:, :), w(:, :)
        integer :: n, b, i, j, row
        n = mesh%nfree
        b = max(mesh%kl, mesh%ku)
        allocate (r(n), jb(fe_band_rows(mesh), n), w(0:b, n))
        call fe_residual(mesh, load, q, r, jb)
        ! lower band of the symmetric part: w(i - j, j) = (A(i, j) + A(j, i))/2
        row = mesh%kl + mesh%ku + 1
        w = 0.0_dp
        do j = 1, n
            do i = j, min(n, j + b)
                if (i - j <= mesh%kl) w(i - j, j) = w(i - j, j) + 0.5_dp*jb(row + i - j, j)
                if (i - j <= mesh%ku) w(i - j, j) = w(i - j, j) + 0.5_dp*jb(row + j - i, i)
            end do
        end do
        call ldlt_inertia(n, b, w, negative)
    end function fe_negative_eigenvalues

    !> Pseudo-arc-length continuation (Keller) of equilibria under the load
    !! load0 + lam * dload, starting from the equilibrium q0 at lam0 (corrected
    !! first by Newton at fixed lam0). Each step predicts along the unit tangent
    !! of the path in (q, lam) space and corrects on the hyperplane normal to it,
    !! so the path is followed through limit points where dlam/ds changes sign.
    !! The Newton matrix is bordered and solved with two banded solves.
    !!
    !! Stops after max_points points (the start included) or when lam leaves
    !! [lam_min, lam_max]; `direction` (+1/-1) orients the first step in lam.
    subroutine fe_path(mesh, load0, dload, q0, lam0, ds, ds_max, direction, lam_min, &
                       lam_max, opts, npts, lam_out, q_out, stat)
        type(fe_mesh_t), intent(in) :: mesh
        type(fe_load_t), intent(in) :: load0, dload
        real(dp), intent(in) :: q0(:)
        real(dp), intent(in) :: lam0, ds, ds_max, lam_min, lam_max
        integer, intent(in) :: direction
        type(fe_newton_opts_t), intent(in) :: opts
        integer, intent(out) :: npts
        real(dp), intent(out) :: lam_out(:), q_out(:, :)
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'fe_path'
        real(dp), allocatable :: q(:), qn(:), r(:), rl(:), jb(:, :), rhs(:, :), tq(:), tq_new(:)
        real(dp) :: lam, lamn, tl, tl_new, h, nrm, g, dl, step, resid
        integer :: it, its, max_points, nfail
        logical :: converged
        type(fe_work_t) :: work

        max_points = size(lam_out)
        npts = 0
        if (size(q0) /= mesh%nfree .or. size(q_out, 1) /= mesh%nfree .or. &
            size(q_out, 2) /= max_points .or. max_points < 1) then
            call set_status(stat, ERR_INPUT, where, 'array sizes do not match nfree = '// &
                            fmt_int(mesh%nfree))
            return
        end if
        if (.not. (ds > 0.0_dp .and. ds_max >= ds)) then
            call set_status(stat, ERR_INPUT, where, 'ds = '//fmt_real(ds)//', ds_max = '// &
                            fmt_real(ds_max)//': expected 0 < ds <= ds_max')
            return
        end if
        if (abs(direction) /= 1) then
            call set_status(stat, ERR_INPUT, where, 'direction = '//fmt_int(direction)// &
                            ', expected +1 or -1')
            return
        end if
        if (.not. (lam_min <= lam0 .and. lam0 <= lam_max)) then
            call set_status(stat, ERR_INPUT, where, 'lam0 = '//fmt_real(lam0)// &
                            ' is outside [lam_min, lam_max]')
            return
        end if
        allocate (q(mesh%nfree), qn(mesh%nfree), r(mesh%nfree), rl(mesh%nfree), &
                  jb(fe_band_rows(mesh), mesh%nfree), rhs(mesh%nfree, 2), &
                  tq(mesh%nfree), tq_new(mesh%nfree))
        call fe_work_init(mesh, work)
        q = q0
        lam = lam0
        call fe_newton(mesh, added(load0, scaled(dload, lam)), q, opts, its, resid, stat, work)
        if (stat%code /= 0) return
        npts = 1
        lam_out(1) = lam
        q_out(:, 1) = q
        ! initial tangent orientation: along +direction in lam
        tq = 0.0_dp
        tl = real(direction, dp)
        h = ds
        nfail = 0
        do while (npts < max_points)
            ! tangent: J z = Q(q; dload), t = (z, 1)/|(z, 1)|, oriented along the last one
            call fe_residual(mesh, added(load0, scaled(dload, lam)), q, r, jb, work)
            call fe_tip_load(mesh, q, dload, rl)   ! -dR/dlam
            rhs(:, 1) = rl
            call solve_banded(mesh%kl, mesh%ku, jb, rhs(:, 1:1), stat)
            if (stat%code /= 0) return
            nrm = sqrt(sum(rhs(:, 1)**2) + 1.0_dp)
            tq_new = rhs(:, 1)/nrm
            tl_new = 1.0_dp/nrm
            if (dot_product(tq_new, tq) + tl_new*tl < 0.0_dp) then
                tq_new = -tq_new
                tl_new = -tl_new
            end if
            tq = tq_new
            tl = tl_new
            qn = q
            lamn = lam
            ! predictor and corrector on the hyperplane t . (x - x_n) = h
            converged = .false.
            q = qn + h*tq
            lam = lamn + h*tl
            do it = 1, opts%max_iter
                call fe_residual(mesh, added(load0, scaled(dload, lam)), q, r, jb, work)
                call fe_tip_load(mesh, q, dload, rl)
                rhs(:, 1) = -r
                rhs(:, 2) = rl
                call solve_banded(mesh%kl, mesh%ku, jb, rhs, stat)
                if (stat%code /= 0) return
                g = dot_product(tq, q - qn) + tl*(lam - lamn) - h
                dl = (-g - dot_product(tq, rhs(:, 1)))/(dot_product(tq, rhs(:, 2)) + tl)
                rhs(:, 1) = rhs(:, 1) + dl*rhs(:, 2)
                q = q + rhs(:, 1)
                lam = lam + dl
                step = max(maxval(abs(rhs(:, 1))), abs(dl))
                if (.not. ieee_is_finite(step)) exit
                if (step <= opts%tol*(1.0_dp + maxval(abs(q)) + abs(lam))) then
                    converged = .true.
                    exit
                end if
            end do
            if (.not. converged) then
                nfail = nfail + 1
                q = qn
                lam = lamn
                h = 0.5_dp*h
                if (nfail > opts%max_bisect) then
                    call set_status(stat, ERR_NO_CONVERGENCE, where, 'corrector failed '// &
                                    'at lam = '//fmt_real(lamn)//' after '// &
                                    fmt_int(opts%max_bisect)//' step halvings')
                    return
                end if
                cycle
            end if
            npts = npts + 1
            lam_out(npts) = lam
            q_out(:, npts) = q
            if (lam < lam_min .or. lam > lam_max) exit
            if (it <= 4) h = min(1.5_dp*h, ds_max)
        end do
    end subroutine fe_path

    !> Geometric stiffness G = int f_i' f_j' ds on the u and w unknowns: the
    !! tangent of a uniform axial force N is K0 + N G (to first order in strain).
    pure subroutine fe_geometric_stiffness(mesh, gb)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(out) :: gb(:, :)
        real(dp) :: f(4), f1(4), f2(4), ge(FE_NDOF, FE_NDOF)
        integer :: el, g, a, b
        gb = 0.0_dp
        do el = 1, mesh%nel
            ge = 0.0_dp
            do g = 1, size(mesh%xg)
                call fe_hermite(mesh%xg(g), mesh%h(el), f, f1, f2)
                do b = 1, 4
                    do a = 1, 4
                        ge(FE_W(a), FE_W(b)) = ge(FE_W(a), FE_W(b)) &
                                               + mesh%wg(g)*mesh%h(el)*f1(a)*f1(b)
                        ge(FE_U(a), FE_U(b)) = ge(FE_U(a), FE_U(b)) &
                                               + mesh%wg(g)*mesh%h(el)*f1(a)*f1(b)
                    end do
                end do
            end do
            call band_scatter(gb, mesh%kl, mesh%ku, mesh%el_free(:, el), ge)
        end do
    end subroutine fe_geometric_stiffness

    !> Critical compressive tip load of the straight chain (linear buckling):
    !! the least P with K0 phi = P G phi, K0 the linear stiffness and G the
    !! geometric stiffness of a unit axial force (a tip force -P along the axis
    !! gives N = -P along the whole chain). The pre-buckling strain (P/EA, about
    !! 1e-6) is neglected. `mode` is the buckled shape scaled to tip w = 1.
    subroutine fe_buckling_load(mesh, pcr, mode, stat)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(out) :: pcr
        real(dp), intent(out) :: mode(:)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: kb(:, :), gb(:, :), k(:, :), g(:, :), w(:)
        integer :: n, itip, ierr
        n = mesh%nfree
        pcr = 0.0_dp
        if (size(mode) /= n) then
            call set_status(stat, ERR_INPUT, 'fe_buckling_load', 'mode has '// &
                            fmt_int(size(mode))//' entries, expected '//fmt_int(n))
            return
        end if
        call fe_check_dense(n, 'fe_buckling_load', stat)
        if (stat%code /= 0) return
        allocate (kb(fe_band_rows(mesh), n), gb(fe_band_rows(mesh), n), k(n, n), g(n, n), &
                  w(n), stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(stat, 'fe_buckling_load', 'the buckling matrices', &
                                 8.0_dp*2.0_dp*real(n, dp)**2)
            return
        end if
        call fe_stiffness_linear(mesh, kb)
        call fe_geometric_stiffness(mesh, gb)
        call band_to_dense(kb, mesh%kl, mesh%ku, k)
        call band_to_dense(gb, mesh%kl, mesh%ku, g)
        call sym_gen_eig(k, g, w, stat)
        if (stat%code /= 0) return
        pcr = w(1)
        mode = k(:, 1)
        itip = mesh%free_of(4*(mesh%nnode - 1) + DOF_W)
        if (mode(itip) /= 0.0_dp) mode = mode/mode(itip)
    end subroutine fe_buckling_load

    !> Static equilibrium held by a radial wire of length wire_length from the
    !! tip to the root (fe_wire_tip): NLT(q) + T e(q) = 0 on the free unknowns
    !! (e = x/|x| on the tip's u and w), |x| = Lw, with the tension T an
    !! unknown (the Lagrange multiplier of the constraint; the arc-length
    !! model's OUT_WIRE_FORCE). Reached by a homotopy: the arm is first bent
    !! by the exact tip moment M0 that makes a circle of chord Lw (fe_solve_static
    !! with load steps), then the moment is taken off in steps, (1 - s) M0
    !! with s = 0 .. 1, each step a bordered Newton solve (fe_wire_bordered) on
    !! (q, T) started from the last; a step that fails is halved. The wire must
    !! end taut (T > 0).
    subroutine fe_solve_wire(mesh, wire_length, q, tension, opts, info, stat)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: wire_length
        real(dp), intent(out) :: q(:), tension
        type(fe_newton_opts_t), intent(in) :: opts
        type(fe_solve_info_t), intent(out) :: info
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'fe_solve_wire'
        real(dp), allocatable :: q_try(:)
        real(dp) :: total, ratio, lo, hi, theta, ei_mean, m0, s, ds, t_try, resid
        integer :: its, nbisect, it
        type(status_t) :: inner
        type(fe_solve_info_t) :: info0
        type(fe_work_t) :: work
        tension = 0.0_dp
        if (size(q) /= mesh%nfree) then
            call set_status(stat, ERR_INPUT, where, 'q has '//fmt_int(size(q))// &
                            ' entries, expected '//fmt_int(mesh%nfree))
            return
        end if
        total = mesh%s(mesh%nnode)
        if (.not. (ieee_is_finite(wire_length) .and. wire_length > 0.05_dp*total .and. &
                   wire_length < total)) then
            call set_status(stat, ERR_INPUT, where, 'wire length Lw = '// &
                            fmt_real(wire_length)//', expected a length between 5 % of the '// &
                            'arm and the arm ('//fmt_real(total)//' m)')
            return
        end if
        ! the circle of length L and chord Lw: sin(theta/2)/(theta/2) = Lw/L
        ratio = wire_length/total
        lo = 0.0_dp
        hi = 6.283185307179586_dp
        do it = 1, 100
            theta = 0.5_dp*(lo + hi)
            if (sin(0.5_dp*theta)/(0.5_dp*theta) > ratio) then
                lo = theta
            else
                hi = theta
            end if
        end do
        ei_mean = total/sum(mesh%h/mesh%ei)
        m0 = theta/total*ei_mean
        call fe_solve_static(mesh, fe_load_t(0.0_dp, 0.0_dp, m0, FE_MOMENT_EXACT), q, &
                             .false., opts, info0, stat)
        if (stat%code /= 0) then
            stat%message = 'the bent start of the radial wire Lw = '// &
                           fmt_real(wire_length)//': '//trim(stat%message)
            return
        end if
        info%iterations = info0%iterations
        info%steps = info0%steps
        call fe_work_init(mesh, work)
        allocate (q_try(mesh%nfree))
        s = -1.0_dp     ! s = 0 first: the wire put on at the full moment
        ds = 1.0_dp
        nbisect = 0
        do while (s < 1.0_dp)
            q_try = q
            t_try = tension
            inner = status_t()
            call fe_wire_bordered(mesh, wire_length, (1.0_dp - min(s + ds, 1.0_dp))*m0, &
                                  q_try, t_try, opts, its, resid, inner, work)
            info%iterations = info%iterations + its
            if (inner%code /= 0) then
                nbisect = nbisect + 1
                if (nbisect > opts%max_bisect .or. s < 0.0_dp) then
                    call set_status(stat, ERR_NO_CONVERGENCE, where, 'radial wire Lw = '// &
                                    fmt_real(wire_length)//': the moment could not be '// &
                                    'taken off past '//fmt_real(max(s, 0.0_dp))// &
                                    ' of the homotopy; last: '//trim(inner%message))
                    return
                end if
                ds = 0.5_dp*ds
                cycle
            end if
            q = q_try
            tension = t_try
            if (s < 0.0_dp) then
                s = 0.0_dp
                ds = 0.25_dp
            else
                s = min(s + ds, 1.0_dp)
                if (its <= 4) ds = min(2.0_dp*ds, 0.5_dp)
            end if
            info%steps = info%steps + 1
            info%residual = resid
        end do
        if (.not. (tension > 0.0_dp)) then
            call set_status(stat, ERR_NO_CONVERGENCE, where, 'radial wire Lw = '// &
                            fmt_real(wire_length)//': the equilibrium found has the '// &
                            'tension '//fmt_real(tension)//' N: no taut-wire shape found')
        end if
    end subroutine fe_solve_wire

    !> Bordered Newton on (q, T) for the wire of length wire_length with the
    !! exact tip moment `moment` beside it: [K_T + T H, e; e^T, 0] (dq, dT) =
    !! -(NLT - Q_M + T e, |x| - Lw), H = (I - e e^T)/|x| (fe_wire_jacobian),
    !! dense (the systems are those of a modal test). `work`: fe_work_init's.
    subroutine fe_wire_bordered(mesh, wire_length, moment, q, tension, opts, iterations, &
                                residual, stat, work)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: wire_length, moment
        real(dp), intent(inout) :: q(:), tension
        type(fe_newton_opts_t), intent(in) :: opts
        integer, intent(out) :: iterations
        real(dp), intent(out) :: residual
        type(status_t), intent(inout) :: stat
        type(fe_work_t), intent(inout) :: work
        character(len=*), parameter :: where = 'fe_wire_bordered'
        real(dp), allocatable :: r(:), jb(:, :), a(:, :), k(:, :), rhs(:, :), qv(:)
        real(dp) :: x(2), rad, step, turn
        type(fe_load_t) :: load
        integer :: n, it, iu, iw
        n = mesh%nfree
        load = fe_load_t(0.0_dp, 0.0_dp, moment, FE_MOMENT_EXACT)
        allocate (r(n), qv(n), jb(fe_band_rows(mesh), n), a(n + 1, n + 1), k(n, n), &
                  rhs(n + 1, 1))
        iterations = 0
        step = huge(1.0_dp)
        do it = 1, opts%max_iter
            iterations = it
            call wire_residual()
            call fe_wire_jacobian(mesh, q, tension, -1.0_dp, jb)
            call fe_band_to_dense(jb, mesh%kl, mesh%ku, k)
            a = 0.0_dp
            a(1:n, 1:n) = k
            a(iu, n + 1) = x(1)/rad
            a(iw, n + 1) = x(2)/rad
            a(n + 1, iu) = x(1)/rad
            a(n + 1, iw) = x(2)/rad
            rhs(1:n, 1) = -r
            rhs(n + 1, 1) = -(rad - wire_length)
            call solve_dense(a, rhs, stat)
            if (stat%code /= 0) return
            turn = max_slope_change(mesh, rhs(1:n, 1))
            if (turn > MAX_TURN) rhs(:, 1) = rhs(:, 1)*(MAX_TURN/turn)
            q = q + rhs(1:n, 1)
            tension = tension + rhs(n + 1, 1)
            step = maxval(abs(rhs(1:n, 1)))
            if (.not. ieee_is_finite(step) .or. step > 1.0e6_dp) then
                call set_status(stat, ERR_NUMERIC, where, 'Newton step became '// &
                                fmt_real(step)//' at iteration '//fmt_int(it))
                return
            end if
            if (step <= opts%tol*(1.0_dp + maxval(abs(q))) .and. &
                abs(rhs(n + 1, 1)) <= opts%tol*(1.0_dp + abs(tension))) then
                call wire_residual()
                residual = max(maxval(abs(r)), abs(rad - wire_length))
                return
            end if
        end do
        call wire_residual()
        residual = max(maxval(abs(r)), abs(rad - wire_length))
        call set_status(stat, ERR_NO_CONVERGENCE, where, 'no convergence in '// &
                        fmt_int(opts%max_iter)//' iterations: last step '// &
                        fmt_real(step)//', residual '//fmt_real(residual)// &
                        ', tolerance '//fmt_real(opts%tol))
    contains
        !> r = NLT - Q_M - Q_wire and jb its Jacobian at fixed T without the
        !! wire's part; x, rad of the tip.
        subroutine wire_residual()
            call fe_residual(mesh, load, q, r, jb, work)
            call fe_wire_force(mesh, q, tension, qv)
            r = r - qv
            call fe_wire_tip(mesh, q, iu, iw, x, rad)
        end subroutine wire_residual
    end subroutine fe_wire_bordered

end module beamid_fe_static
