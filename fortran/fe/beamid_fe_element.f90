!> Pure kernels of the Epstein-Murray nonlinear beam element (Chapter IV).
!!
!! One element of length h carries eight unknowns in the dissertation's node
!! order (Eq. 83): [w1, w1', u1, u1', w2, w2', u2, u2'], where ' is d/ds along
!! the undeformed axis. Both u and w use the cubic Hermite functions of Eq. 76.
!! The strain measures are the Green axial strain (Eq. 70) and the modified
!! curvature (Eq. 72),
!!
!!     e   = u' + (u'^2 + w'^2)/2,      chi = w''(1 + u') - w' u'',
!!
!! and the potential is (Eq. 87, with the optional cubic moment law of Eq. 16)
!!
!!     V = int_0^h ( EA e^2/2 + EI chi^2/2 + C chi^4/4 ) ds.
!!
!! The internal force is dV/dq and the tangent d^2V/dq^2, both hand-coded.
!! With u' of degree 2, e has degree 4 and chi degree 3 in s, so every
!! integrand of the force, the tangent and V has degree at most 8 when C = 0
!! (12 when C /= 0): Gauss-Legendre with 5 (7) points integrates them exactly.
module beamid_fe_element
    use beamid_kinds, only: dp, pi
    implicit none
    private

    public :: FE_NDOF, FE_W, FE_U
    public :: fe_gauss_points, fe_quadrature_order, fe_hermite
    public :: fe_element_energy, fe_element_force, fe_element_tangent
    public :: fe_element_mass, fe_element_strain
    public :: fe_gauss_table, fe_element_force_tabulated, fe_element_tangent_tabulated
    public :: fe_hinge_energy, fe_hinge_force, fe_hinge_tangent
    public :: fe_element_tangent_dir, fe_hinge_tangent_dir, fe_angle_hessian_dir

    !> Unknowns per element.
    integer, parameter :: FE_NDOF = 8
    !> Positions of the w and u Hermite coefficients in the element vector,
    !! in the order of the shape functions f1..f4 (Eq. 76).
    integer, parameter :: FE_W(4) = [1, 2, 5, 6]
    integer, parameter :: FE_U(4) = [3, 4, 7, 8]

    ! The reduced element. f1 + f3 = 1 (Eq. 76) gives f3' = -f1', f3'' = -f1''
    ! (fe_hermite computes the two as exact negatives), so in de/dq, dchi/dq,
    ! the force and the tangent the entries of w2 and u2 are minus those of
    ! w1 and u1: the rigid translations leave e and chi unchanged. The
    ! tabulated kernels work on the six reduced unknowns
    ! [w1, w1', u1, u1', w2', u2'] (element unknowns 1, 2, 3, 4, 6, 8) and
    ! expand once per element, f = S f_red(R), k = S k_red(R, R) S.
    integer, parameter :: RED_NDOF = 6
    !> Shape functions kept in the reduced element.
    integer, parameter :: RED_SHAPE(3) = [1, 2, 4]
    !> Reduced positions of w and of u for the shape functions RED_SHAPE.
    integer, parameter :: RED_W(3) = [1, 2, 5]
    integer, parameter :: RED_U(3) = [3, 4, 6]
    !> R: reduced position of each element unknown.
    integer, parameter :: RED_OF(FE_NDOF) = [1, 2, 3, 4, 1, 5, 3, 6]
    !> S: sign of each element unknown relative to its reduced one.
    real(dp), parameter :: RED_SIGN(FE_NDOF) = [1.0_dp, 1.0_dp, 1.0_dp, 1.0_dp, &
                                                -1.0_dp, 1.0_dp, -1.0_dp, 1.0_dp]

contains

    !> Number of Gauss points that integrates the element exactly:
    !! 5 for the polynomial degree 8 of Eq. 87 with C = 0, 7 for degree 12.
    pure integer function fe_quadrature_order(cubic)
        real(dp), intent(in) :: cubic
        if (cubic == 0.0_dp) then
            fe_quadrature_order = 5
        else
            fe_quadrature_order = 7
        end if
    end function fe_quadrature_order

    !> Gauss-Legendre points `x` and weights `w` on [0, 1] (n >= 1), by Newton
    !! iteration on the Legendre polynomial from Chebyshev-like starting values.
    pure subroutine fe_gauss_points(n, x, w)
        integer, intent(in) :: n
        real(dp), intent(out) :: x(n), w(n)
        real(dp) :: z, p, dp_dz, dz
        integer :: i, it
        do i = 1, n
            z = cos(pi*(real(i, dp) - 0.25_dp)/(real(n, dp) + 0.5_dp))
            do it = 1, 100
                call legendre(n, z, p, dp_dz)
                dz = p/dp_dz
                z = z - dz
                if (abs(dz) <= 1.0e-16_dp) exit
            end do
            call legendre(n, z, p, dp_dz)
            ! z decreases with i, so x = (1 - z)/2 comes out ascending
            x(i) = 0.5_dp*(1.0_dp - z)
            w(i) = 1.0_dp/((1.0_dp - z*z)*dp_dz*dp_dz)
        end do
    end subroutine fe_gauss_points

    !> The Legendre polynomial P_n(z) by its three-term recurrence, and P_n'(z).
    pure subroutine legendre(n, z, p1, dp_dz)
        integer, intent(in) :: n
        real(dp), intent(in) :: z
        real(dp), intent(out) :: p1, dp_dz
        real(dp) :: p0, p2
        integer :: j
        p0 = 1.0_dp
        p1 = z
        do j = 2, n
            p2 = ((2*j - 1)*z*p1 - (j - 1)*p0)/real(j, dp)
            p0 = p1
            p1 = p2
        end do
        dp_dz = n*(z*p1 - p0)/(z*z - 1.0_dp)
    end subroutine legendre

    !> Cubic Hermite functions of Eq. 76 at zeta = s/h, with their first and
    !! second derivatives with respect to s.
    pure subroutine fe_hermite(zeta, h, f, f1, f2)
        real(dp), intent(in) :: zeta, h
        real(dp), intent(out) :: f(4), f1(4), f2(4)
        real(dp) :: z2, z3
        z2 = zeta*zeta
        z3 = z2*zeta
        f = [1.0_dp - 3.0_dp*z2 + 2.0_dp*z3, h*(zeta - 2.0_dp*z2 + z3), &
             3.0_dp*z2 - 2.0_dp*z3, h*(-z2 + z3)]
        f1 = [(-6.0_dp*zeta + 6.0_dp*z2)/h, 1.0_dp - 4.0_dp*zeta + 3.0_dp*z2, &
              (6.0_dp*zeta - 6.0_dp*z2)/h, -2.0_dp*zeta + 3.0_dp*z2]
        f2 = [(-6.0_dp + 12.0_dp*zeta)/(h*h), (-4.0_dp + 6.0_dp*zeta)/h, &
              (6.0_dp - 12.0_dp*zeta)/(h*h), (-2.0_dp + 6.0_dp*zeta)/h]
    end subroutine fe_hermite

    !> Axial strain e (Eq. 70), curvature chi (Eq. 72) and u', w' at zeta.
    pure subroutine fe_element_strain(h, qe, zeta, e, chi, du, dw)
        real(dp), intent(in) :: h, qe(FE_NDOF), zeta
        real(dp), intent(out) :: e, chi, du, dw
        real(dp) :: f(4), f1(4), f2(4), d2u, d2w
        call fe_hermite(zeta, h, f, f1, f2)
        du = dot_product(f1, qe(FE_U))
        dw = dot_product(f1, qe(FE_W))
        d2u = dot_product(f2, qe(FE_U))
        d2w = dot_product(f2, qe(FE_W))
        e = du + 0.5_dp*(du*du + dw*dw)
        chi = d2w*(1.0_dp + du) - dw*d2u
    end subroutine fe_element_strain

    !> Strain energy of one element (Eq. 87 plus C chi^4/4).
    pure function fe_element_energy(h, ea, ei, cubic, xg, wg, qe) result(v)
        real(dp), intent(in) :: h, ea, ei, cubic
        real(dp), intent(in) :: xg(:), wg(:)   !< Gauss points and weights on [0, 1]
        real(dp), intent(in) :: qe(FE_NDOF)
        real(dp) :: v
        real(dp) :: e, chi, du, dw
        integer :: g
        v = 0.0_dp
        do g = 1, size(xg)
            call fe_element_strain(h, qe, xg(g), e, chi, du, dw)
            v = v + wg(g)*(0.5_dp*ea*e*e + 0.5_dp*ei*chi*chi + 0.25_dp*cubic*chi**4)
        end do
        v = v*h
    end function fe_element_energy

    !> Hermite derivatives of Eq. 76 at the Gauss points of an element of
    !! length h: d1(:, g) = df/ds and d2(:, g) = d2f/ds2 at s = xg(g) h, and
    !! the weights wh(g) = wg(g) h of the integral over [0, h]. They depend on
    !! h only, so a mesh tabulates them once (fe_mesh_build) for the
    !! fe_element_*_tabulated kernels.
    pure subroutine fe_gauss_table(h, xg, wg, d1, d2, wh)
        real(dp), intent(in) :: h
        real(dp), intent(in) :: xg(:), wg(:)   !< Gauss points and weights on [0, 1]
        real(dp), intent(out) :: d1(4, size(xg)), d2(4, size(xg)), wh(size(xg))
        real(dp) :: f(4)
        integer :: g
        do g = 1, size(xg)
            call fe_hermite(xg(g), h, f, d1(:, g), d2(:, g))
            wh(g) = wg(g)*h
        end do
    end subroutine fe_gauss_table

    !> Strains at one Gauss point from the tabulated Hermite derivatives g1 =
    !! f', g2 = f'' of the shape functions RED_SHAPE and the reduced nodal
    !! values qw, qu (reduced_dofs): a = u', b = w', c = u'', d = w'',
    !! e (Eq. 70), chi (Eq. 72). The strain gradients are linear in g1, g2
    !! (see the callers):
    !!     de/dU = (1 + a) g1,     de/dW = b g1,
    !!     dchi/dU = d g1 - b g2,  dchi/dW = (1 + a) g2 - c g1.
    pure subroutine gauss_strains(g1, g2, qw, qu, a, b, c, d, e, chi)
        real(dp), intent(in) :: g1(3), g2(3), qw(3), qu(3)
        real(dp), intent(out) :: a, b, c, d, e, chi
        a = g1(1)*qu(1) + g1(2)*qu(2) + g1(3)*qu(3)
        b = g1(1)*qw(1) + g1(2)*qw(2) + g1(3)*qw(3)
        c = g2(1)*qu(1) + g2(2)*qu(2) + g2(3)*qu(3)
        d = g2(1)*qw(1) + g2(2)*qw(2) + g2(3)*qw(3)
        e = a + 0.5_dp*(a*a + b*b)
        chi = d*(1.0_dp + a) - b*c
    end subroutine gauss_strains

    !> Nodal values of w and u that multiply f1', f2', f4' (and f''): with
    !! f3 = 1 - f1, w' = f1' (w1 - w2) + f2' w1' + f4' w2' (Eq. 76), alike u.
    pure subroutine reduced_dofs(qe, qw, qu)
        real(dp), intent(in) :: qe(FE_NDOF)
        real(dp), intent(out) :: qw(3), qu(3)
        qw = [qe(FE_W(1)) - qe(FE_W(3)), qe(FE_W(2)), qe(FE_W(4))]
        qu = [qe(FE_U(1)) - qe(FE_U(3)), qe(FE_U(2)), qe(FE_U(4))]
    end subroutine reduced_dofs

    !> Internal force dV/dq of one element (the element part of NLT, Eq. 79-83).
    pure subroutine fe_element_force(h, ea, ei, cubic, xg, wg, qe, f)
        real(dp), intent(in) :: h, ea, ei, cubic
        real(dp), intent(in) :: xg(:), wg(:)
        real(dp), intent(in) :: qe(FE_NDOF)
        real(dp), intent(out) :: f(FE_NDOF)
        real(dp) :: d1(4, size(xg)), d2(4, size(xg)), wh(size(xg))
        call fe_gauss_table(h, xg, wg, d1, d2, wh)
        call fe_element_force_tabulated(size(xg), d1, d2, wh, ea, ei, cubic, qe, f)
    end subroutine fe_element_force

    !> fe_element_force from the Hermite derivatives d1, d2 and weights wh of
    !! fe_gauss_table (ng Gauss points). With N = EA e and M = EI chi + C chi^3
    !! the force is sum_g wh (N de/dq + M dchi/dq), i.e. per shape function
    !! f_U = wh [(N (1 + a) + M d) g1 - M b g2],
    !! f_W = wh [(N b - M c) g1 + M (1 + a) g2],
    !! summed on the reduced unknowns (RED_* above; the tables must have
    !! d(3, :) = -d(1, :), as fe_gauss_table gives) and expanded at the end.
    pure subroutine fe_element_force_tabulated(ng, d1, d2, wh, ea, ei, cubic, qe, f)
        integer, intent(in) :: ng
        real(dp), intent(in) :: d1(4, ng), d2(4, ng), wh(ng)
        real(dp), intent(in) :: ea, ei, cubic
        real(dp), intent(in) :: qe(FE_NDOF)
        real(dp), intent(out) :: f(FE_NDOF)
        real(dp) :: a, b, c, d, e, chi, axial, moment, cu1, cu2, cw1, cw2
        real(dp) :: qw(3), qu(3), g1(3), g2(3), f_red(RED_NDOF)
        integer :: g
        call reduced_dofs(qe, qw, qu)
        f_red = 0.0_dp
        do g = 1, ng
            ! the strains of gauss_strains, written out in this hottest loop
            ! (the compiler inlines a helper with a single caller only)
            g1 = d1(RED_SHAPE, g)
            g2 = d2(RED_SHAPE, g)
            a = g1(1)*qu(1) + g1(2)*qu(2) + g1(3)*qu(3)
            b = g1(1)*qw(1) + g1(2)*qw(2) + g1(3)*qw(3)
            c = g2(1)*qu(1) + g2(2)*qu(2) + g2(3)*qu(3)
            d = g2(1)*qw(1) + g2(2)*qw(2) + g2(3)*qw(3)
            e = a + 0.5_dp*(a*a + b*b)
            chi = d*(1.0_dp + a) - b*c
            axial = wh(g)*ea*e
            moment = wh(g)*(ei*chi + cubic*chi**3)
            cu1 = axial*(1.0_dp + a) + moment*d
            cu2 = -moment*b
            cw1 = axial*b - moment*c
            cw2 = moment*(1.0_dp + a)
            ! written out so that [w1, w1'] and [u1, u1'] go as pairs
            f_red(1:2) = f_red(1:2) + cw1*g1(1:2) + cw2*g2(1:2)
            f_red(3:4) = f_red(3:4) + cu1*g1(1:2) + cu2*g2(1:2)
            f_red(5) = f_red(5) + cw1*g1(3) + cw2*g2(3)
            f_red(6) = f_red(6) + cu1*g1(3) + cu2*g2(3)
        end do
        ! S f_red(R), spelt out: an index vector would keep f_red in memory
        f = [f_red(1:4), -f_red(1), f_red(5), -f_red(3), f_red(6)]
    end subroutine fe_element_force_tabulated

    !> Internal force and tangent stiffness d^2V/dq^2 of one element (Eq. 85).
    pure subroutine fe_element_tangent(h, ea, ei, cubic, xg, wg, qe, f, k)
        real(dp), intent(in) :: h, ea, ei, cubic
        real(dp), intent(in) :: xg(:), wg(:)
        real(dp), intent(in) :: qe(FE_NDOF)
        real(dp), intent(out) :: f(FE_NDOF), k(FE_NDOF, FE_NDOF)
        real(dp) :: d1(4, size(xg)), d2(4, size(xg)), wh(size(xg))
        call fe_gauss_table(h, xg, wg, d1, d2, wh)
        call fe_element_tangent_tabulated(size(xg), d1, d2, wh, ea, ei, cubic, qe, k, f)
    end subroutine fe_element_tangent

    !> fe_element_tangent from the tables of fe_gauss_table. Per Gauss point
    !! the tangent is wh [EA de de^T + (EI + 3 C chi^2) dchi dchi^T
    !! + N d2e/dq2 + M d2chi/dq2]. Everything is accumulated on the six reduced
    !! unknowns (RED_* above; the tables must have d(3, :) = -d(1, :), as
    !! fe_gauss_table gives) and expanded to 8 x 8 once. The first two terms
    !! are symmetric: only the upper triangle is accumulated and mirrored at
    !! the end. The second derivatives are constant matrices in g1, g2:
    !! d2e/dq2 is g1 g1^T on the uu and the ww blocks (Eq. 70),
    !! d2chi/dU_i dW_j = g1_i g2_j - g2_i g1_j (Eq. 72); their weighted sums
    !! over the Gauss points are accumulated as 3 x 3 blocks and added once.
    pure subroutine fe_element_tangent_tabulated(ng, d1, d2, wh, ea, ei, cubic, qe, k, f)
        integer, intent(in) :: ng
        real(dp), intent(in) :: d1(4, ng), d2(4, ng), wh(ng)
        real(dp), intent(in) :: ea, ei, cubic
        real(dp), intent(in) :: qe(FE_NDOF)
        real(dp), intent(out) :: k(FE_NDOF, FE_NDOF)
        !> the internal force (absent: the stiffness alone, some 15 % faster,
        !! as the sensitivities' stage Jacobians want it)
        real(dp), intent(out), optional :: f(FE_NDOF)
        real(dp) :: a, b, c, d, e, chi, axial, moment, stiff_e, stiff_chi
        real(dp) :: cu1, cu2, cw1, cw2
        real(dp) :: qw(3), qu(3)
        ! f' and f'' of the shape functions RED_SHAPE at one Gauss point
        real(dp) :: g1(3), g2(3)
        real(dp) :: de(RED_NDOF), dchi(RED_NDOF), sde(RED_NDOF), sdchi(RED_NDOF)
        real(dp) :: f_red(RED_NDOF), k_red(RED_NDOF, RED_NDOF)
        ! sum of N g1 g1^T (uu and ww blocks) and of M (g1 g2^T - g2 g1^T) (uw block)
        real(dp) :: k_axial(3, 3), k_moment(3, 3)
        integer :: g, i, j, iw, ju
        call reduced_dofs(qe, qw, qu)
        f_red = 0.0_dp
        k_red = 0.0_dp
        k_axial = 0.0_dp
        k_moment = 0.0_dp
        do g = 1, ng
            g1 = d1(RED_SHAPE, g)
            g2 = d2(RED_SHAPE, g)
            call gauss_strains(g1, g2, qw, qu, a, b, c, d, e, chi)
            axial = wh(g)*ea*e
            moment = wh(g)*(ei*chi + cubic*chi**3)
            stiff_e = wh(g)*ea
            stiff_chi = wh(g)*(ei + 3.0_dp*cubic*chi*chi)
            cu1 = axial*(1.0_dp + a) + moment*d
            cu2 = -moment*b
            cw1 = axial*b - moment*c
            cw2 = moment*(1.0_dp + a)
            if (present(f)) then
                ! written out as in fe_element_force_tabulated
                f_red(1:2) = f_red(1:2) + cw1*g1(1:2) + cw2*g2(1:2)
                f_red(3:4) = f_red(3:4) + cu1*g1(1:2) + cu2*g2(1:2)
                f_red(5) = f_red(5) + cw1*g1(3) + cw2*g2(3)
                f_red(6) = f_red(6) + cu1*g1(3) + cu2*g2(3)
            end if
            de(RED_W) = b*g1
            de(RED_U) = (1.0_dp + a)*g1
            dchi(RED_W) = (1.0_dp + a)*g2 - c*g1
            dchi(RED_U) = d*g1 - b*g2
            sde = stiff_e*de
            sdchi = stiff_chi*dchi
            ! unrolled: the pairs stay in registers (stack arrays stored per entry and
            ! read back in pairs stall the store forwarding; 8 % of this routine)
            !GCC$ unroll 6
            do j = 1, RED_NDOF
                !GCC$ unroll 6
                do i = 1, j + mod(j, 2), 2
                    k_red(i, j) = k_red(i, j) + sde(i)*de(j) + sdchi(i)*dchi(j)
                    k_red(i + 1, j) = k_red(i + 1, j) + sde(i + 1)*de(j) + sdchi(i + 1)*dchi(j)
                end do
            end do
            do j = 1, 3
                do i = 1, j
                    k_axial(i, j) = k_axial(i, j) + axial*g1(i)*g1(j)
                end do
                do i = 1, j - 1
                    k_moment(i, j) = k_moment(i, j) + moment*(g1(i)*g2(j) - g2(i)*g1(j))
                end do
            end do
        end do
        ! second-derivative blocks into the upper triangle (RED_W and RED_U
        ! ascend): k_axial on ww and uu; the entry of W_i and U_j takes
        ! k_moment(j, i), k_moment being antisymmetric with a zero diagonal
        do j = 1, 3
            do i = 1, j
                k_red(RED_W(i), RED_W(j)) = k_red(RED_W(i), RED_W(j)) + k_axial(i, j)
                k_red(RED_U(i), RED_U(j)) = k_red(RED_U(i), RED_U(j)) + k_axial(i, j)
            end do
        end do
        do j = 1, 3
            do i = 1, 3
                if (i == j) cycle
                iw = min(RED_W(i), RED_U(j))
                ju = max(RED_W(i), RED_U(j))
                if (i < j) then
                    k_red(iw, ju) = k_red(iw, ju) - k_moment(i, j)
                else
                    k_red(iw, ju) = k_red(iw, ju) + k_moment(j, i)
                end if
            end do
        end do
        do j = 1, RED_NDOF
            do i = j + 1, RED_NDOF
                k_red(i, j) = k_red(j, i)
            end do
        end do
        if (present(f)) f = [f_red(1:4), -f_red(1), f_red(5), -f_red(3), f_red(6)]
        do j = 1, FE_NDOF
            do i = 1, FE_NDOF
                k(i, j) = RED_SIGN(i)*RED_SIGN(j)*k_red(RED_OF(i), RED_OF(j))
            end do
        end do
    end subroutine fe_element_tangent_tabulated

    !> Consistent mass matrix rho h F_jk of one element (Eq. 92-97), for the
    !! u and the w unknowns alike.
    pure subroutine fe_element_mass(h, rho, m)
        real(dp), intent(in) :: h, rho
        real(dp), intent(out) :: m(FE_NDOF, FE_NDOF)
        real(dp) :: xg(4), wg(4), f(4), f1(4), f2(4)
        integer :: g, i, j
        call fe_gauss_points(4, xg, wg)
        m = 0.0_dp
        do g = 1, 4
            call fe_hermite(xg(g), h, f, f1, f2)
            do j = 1, 4
                do i = 1, 4
                    m(FE_W(i), FE_W(j)) = m(FE_W(i), FE_W(j)) + wg(g)*rho*h*f(i)*f(j)
                    m(FE_U(i), FE_U(j)) = m(FE_U(i), FE_U(j)) + wg(g)*rho*h*f(i)*f(j)
                end do
            end do
        end do
    end subroutine fe_element_mass

    !> Relative rotation dpsi = psi+ - psi- of a hinge (Section 8 of
    !! docs/theory_fe.md) between the tangents t- = (1 + u'-, w'-) and
    !! t+ = (1 + u'+, w'+), psi = atan2(w', 1 + u') the cross-section angle of
    !! the shear-free element, and its gradient g with respect to the hinge
    !! vector s = [w'-, u'-, w'+, u'+]. dpsi = atan2(t- x t+, t- . t+) lies in
    !! (-pi, pi]: no branch cut of the single angles is crossed.
    pure subroutine hinge_angle(s, dpsi, g)
        real(dp), intent(in) :: s(4)
        real(dp), intent(out) :: dpsi, g(4)
        real(dp) :: xm, ym, xp, yp, rm, rp
        ym = s(1)
        xm = 1.0_dp + s(2)
        yp = s(3)
        xp = 1.0_dp + s(4)
        rm = xm*xm + ym*ym
        rp = xp*xp + yp*yp
        dpsi = atan2(xm*yp - ym*xp, xm*xp + ym*yp)
        g = [-xm/rm, ym/rm, xp/rp, -yp/rp]
    end subroutine hinge_angle

    !> Energy dpsi^2 / (2 flex) of a hinge spring of compliance flex > 0 (rad
    !! per N m) on s = [w'-, u'-, w'+, u'+].
    pure real(dp) function fe_hinge_energy(flex, s) result(v)
        real(dp), intent(in) :: flex, s(4)
        real(dp) :: dpsi, g(4)
        call hinge_angle(s, dpsi, g)
        v = 0.5_dp*dpsi*dpsi/flex
    end function fe_hinge_energy

    !> Generalized force (dpsi / flex) d(dpsi)/ds of a hinge spring: the hinge
    !! moment M = dpsi / flex times the angle gradient (the kink dpsi = f M).
    pure subroutine fe_hinge_force(flex, s, f)
        real(dp), intent(in) :: flex, s(4)
        real(dp), intent(out) :: f(4)
        real(dp) :: dpsi, g(4)
        call hinge_angle(s, dpsi, g)
        f = (dpsi/flex)*g
    end subroutine fe_hinge_force

    !> Force and tangent (g g^T + dpsi H) / flex of a hinge spring, with H the
    !! Hessian of dpsi: -Hess(psi-) and +Hess(psi+) on the diagonal blocks,
    !! Hess(psi) = [-2xy, y^2 - x^2; y^2 - x^2, 2xy] / r^4 on (w', u').
    pure subroutine fe_hinge_tangent(flex, s, f, k)
        real(dp), intent(in) :: flex, s(4)
        real(dp), intent(out) :: f(4), k(4, 4)
        real(dp) :: dpsi, g(4), x, y, r4, m
        integer :: i, j, side
        call hinge_angle(s, dpsi, g)
        m = dpsi/flex
        f = m*g
        do j = 1, 4
            do i = 1, 4
                k(i, j) = g(i)*g(j)/flex
            end do
        end do
        do side = 0, 1
            y = s(2*side + 1)
            x = 1.0_dp + s(2*side + 2)
            r4 = (x*x + y*y)**2
            ! psi- enters dpsi with sign -1, psi+ with +1
            if (side == 0) then
                r4 = -r4
            end if
            i = 2*side + 1
            k(i, i) = k(i, i) + m*(-2.0_dp*x*y)/r4
            k(i + 1, i + 1) = k(i + 1, i + 1) + m*(2.0_dp*x*y)/r4
            k(i, i + 1) = k(i, i + 1) + m*(y*y - x*x)/r4
            k(i + 1, i) = k(i + 1, i) + m*(y*y - x*x)/r4
        end do
    end subroutine fe_hinge_tangent

    !> Directional derivative (dk/dq)[ve] of the element tangent k = d^2V/dq^2
    !! of fe_element_tangent along the element vector ve (the third derivative
    !! of V contracted with ve), hand-coded. Per Gauss point, with N = EA e,
    !! M = EI chi + C chi^3, S = EI + 3 C chi^2, de = de/dq, dchi = dchi/dq
    !! and the constant Hessians He = d2e/dq2, Hc = d2chi/dq2 (e and chi are
    !! quadratic in q, so their third derivatives vanish):
    !!     k  = wh [EA de de^T + S dchi dchi^T + N He + M Hc],
    !!     dk = wh [EA (He ve de^T + de (He ve)^T) + 6 C chi (dchi.ve) dchi dchi^T
    !!            + S (Hc ve dchi^T + dchi (Hc ve)^T) + EA (de.ve) He + S (dchi.ve) Hc].
    pure subroutine fe_element_tangent_dir(h, ea, ei, cubic, xg, wg, qe, ve, dk)
        real(dp), intent(in) :: h, ea, ei, cubic
        real(dp), intent(in) :: xg(:), wg(:)   !< Gauss points and weights on [0, 1]
        real(dp), intent(in) :: qe(FE_NDOF), ve(FE_NDOF)
        real(dp), intent(out) :: dk(FE_NDOF, FE_NDOF)
        real(dp) :: f(4), g1(4), g2(4), a, b, c, d, chi, va, vb, vc, vd, wt, stiff, dstiff, &
                    rate_e, rate_chi, hm
        real(dp) :: de(FE_NDOF), dchi(FE_NDOF), hev(FE_NDOF), hcv(FE_NDOF)
        integer :: g, i, j
        dk = 0.0_dp
        do g = 1, size(xg)
            call fe_hermite(xg(g), h, f, g1, g2)
            a = dot_product(g1, qe(FE_U))
            b = dot_product(g1, qe(FE_W))
            c = dot_product(g2, qe(FE_U))
            d = dot_product(g2, qe(FE_W))
            va = dot_product(g1, ve(FE_U))
            vb = dot_product(g1, ve(FE_W))
            vc = dot_product(g2, ve(FE_U))
            vd = dot_product(g2, ve(FE_W))
            chi = d*(1.0_dp + a) - b*c
            de(FE_U) = (1.0_dp + a)*g1
            de(FE_W) = b*g1
            dchi(FE_U) = d*g1 - b*g2
            dchi(FE_W) = (1.0_dp + a)*g2 - c*g1
            ! He ve: g1 g1^T on the uu and the ww blocks
            hev(FE_U) = va*g1
            hev(FE_W) = vb*g1
            ! Hc ve: d2chi/dU_i dW_j = g1_i g2_j - g2_i g1_j
            hcv(FE_U) = vd*g1 - vb*g2
            hcv(FE_W) = va*g2 - vc*g1
            rate_e = dot_product(de, ve)
            rate_chi = dot_product(dchi, ve)
            wt = wg(g)*h
            stiff = ei + 3.0_dp*cubic*chi*chi
            dstiff = 6.0_dp*cubic*chi*rate_chi
            do j = 1, FE_NDOF
                do i = 1, FE_NDOF
                    dk(i, j) = dk(i, j) + wt*(ea*(hev(i)*de(j) + de(i)*hev(j)) &
                                              + dstiff*dchi(i)*dchi(j) &
                                              + stiff*(hcv(i)*dchi(j) + dchi(i)*hcv(j)))
                end do
            end do
            do j = 1, 4
                do i = 1, 4
                    hm = wt*ea*rate_e*g1(i)*g1(j)
                    dk(FE_U(i), FE_U(j)) = dk(FE_U(i), FE_U(j)) + hm
                    dk(FE_W(i), FE_W(j)) = dk(FE_W(i), FE_W(j)) + hm
                    hm = wt*stiff*rate_chi*(g1(i)*g2(j) - g2(i)*g1(j))
                    dk(FE_U(i), FE_W(j)) = dk(FE_U(i), FE_W(j)) + hm
                    dk(FE_W(j), FE_U(i)) = dk(FE_W(j), FE_U(i)) + hm
                end do
            end do
        end do
    end subroutine fe_element_tangent_dir

    !> Hessian of the angle psi = atan2(y, x) on (y, x) is [ha, hb; hb, -ha],
    !! ha = -2xy/r^4, hb = (y^2 - x^2)/r^4; this returns ha, hb and their
    !! directional derivatives along (dy, dx): psi is harmonic, so
    !! dha = P dx + Q dy, dhb = -Q dx + P dy with
    !! P = (6x^2 y - 2y^3)/r^6, Q = (6x y^2 - 2x^3)/r^6.
    pure subroutine fe_angle_hessian_dir(x, y, dx, dy, ha, hb, dha, dhb)
        real(dp), intent(in) :: x, y, dx, dy
        real(dp), intent(out) :: ha, hb, dha, dhb
        real(dp) :: r2, r4, r6, pp, qq
        r2 = x*x + y*y
        r4 = r2*r2
        r6 = r4*r2
        ha = -2.0_dp*x*y/r4
        hb = (y*y - x*x)/r4
        pp = (6.0_dp*x*x*y - 2.0_dp*y**3)/r6
        qq = (6.0_dp*x*y*y - 2.0_dp*x**3)/r6
        dha = pp*dx + qq*dy
        dhb = -qq*dx + pp*dy
    end subroutine fe_angle_hessian_dir

    !> Directional derivative along vs of the hinge tangent
    !! K = (g g^T + dpsi H)/flex of fe_hinge_tangent (hand-coded):
    !! dK = ((H vs) g^T + g (H vs)^T + (g.vs) H + dpsi dH)/flex, dH the
    !! derivative of the Hessians of psi- and psi+ (fe_angle_hessian_dir).
    pure subroutine fe_hinge_tangent_dir(flex, s, vs, dk)
        real(dp), intent(in) :: flex, s(4), vs(4)
        real(dp), intent(out) :: dk(4, 4)
        real(dp) :: dpsi, g(4), hm(4, 4), dh(4, 4), hv(4), sg, ha, hb, dha, dhb
        integer :: i, j, side
        call hinge_angle(s, dpsi, g)
        hm = 0.0_dp
        dh = 0.0_dp
        do side = 0, 1
            i = 2*side + 1
            ! psi- enters dpsi with sign -1, psi+ with +1
            sg = merge(-1.0_dp, 1.0_dp, side == 0)
            call fe_angle_hessian_dir(1.0_dp + s(i + 1), s(i), vs(i + 1), vs(i), ha, hb, dha, dhb)
            hm(i:i + 1, i:i + 1) = sg*reshape([ha, hb, hb, -ha], [2, 2])
            dh(i:i + 1, i:i + 1) = sg*reshape([dha, dhb, dhb, -dha], [2, 2])
        end do
        hv = matmul(hm, vs)
        do j = 1, 4
            do i = 1, 4
                dk(i, j) = (hv(i)*g(j) + g(i)*hv(j) + dot_product(g, vs)*hm(i, j) &
                            + dpsi*dh(i, j))/flex
            end do
        end do
    end subroutine fe_hinge_tangent_dir

end module beamid_fe_element
