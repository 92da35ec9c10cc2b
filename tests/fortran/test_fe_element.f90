!> The element kernels of the nonlinear finite element chain (Chapter IV,
!! fortran/fe/beamid_fe_element.f90) and the banded tangent assembly
!! (beamid_fe_assembly):
!! * the Gauss-point element force against the dissertation's F-tensor form
!!   (Eq. 77): contractions of the nodal values with exact integrals of
!!   products of shape-function derivatives, built here from the polynomial
!!   coefficients of Eq. 76;
!! * hand-coded force and tangent against fourth-order central differences of
!!   the energy and of the force (cubic moment law off and on, and at 25
!!   random states, lengths and cubic coefficients);
!! * the consistent mass integrates mass and second moments exactly;
!! * the reduced element (f1 + f3 = 1): a rigid translation changes nothing;
!! * the assembled banded tangent of a hinged chain against central
!!   differences of the assembled internal force.
program test_fe_element
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK
    use beamid_model, only: chain_t, chain_from_vector, param_name
    use beamid_presets, only: preset_params
    use beamid_fe_element, only: FE_NDOF, FE_W, FE_U, fe_gauss_points, fe_quadrature_order, &
                                 fe_element_energy, fe_element_force, fe_element_tangent, &
                                 fe_element_mass
    use beamid_fe_assembly, only: fe_mesh_t, fe_mesh_build, fe_band_rows, fe_tangent, &
                                  fe_internal_force, fe_work_t, fe_work_init
    use beamid_band, only: band_to_dense
    use beamid_testing, only: checks_t, check_close, check_true, check_finish, seed_random
    implicit none

    !> Highest polynomial degree kept (products of four cubics: 12).
    integer, parameter :: DEG = 15
    type(checks_t) :: t
    integer :: i

    call seed_random(20261124)
    do i = 1, 3
        call f_tensor_form(0.388_dp, 1.37e7_dp, 11.4_dp)
    end do
    call central_differences(0.25_dp, 2.0e5_dp, 11.3_dp, 0.0_dp)
    call central_differences(0.25_dp, 2.0e5_dp, 11.3_dp, 7.5_dp)
    call tangent_property(25)
    call mass_integrates_exactly()
    call rigid_translation(0.31_dp, 2.0e5_dp, 11.3_dp, 0.0_dp)
    call rigid_translation(0.31_dp, 2.0e5_dp, 11.3_dp, 7.5_dp)
    call node_two_mirrors_node_one(0.22_dp, 1.0e5_dp, 9.0_dp, 0.0_dp)
    call node_two_mirrors_node_one(0.22_dp, 1.0e5_dp, 9.0_dp, 7.5_dp)
    call assembled_tangent()
    call check_finish(t, 'test_fe_element')

contains

    !> Energy, force, tangent and mass of one element with the exact Gauss rule.
    subroutine element(h, ea, ei, cubic, rho, qe, energy, force, tangent, mass)
        real(dp), intent(in) :: h, ea, ei, cubic, rho, qe(FE_NDOF)
        real(dp), intent(out) :: energy, force(FE_NDOF), tangent(FE_NDOF, FE_NDOF)
        real(dp), intent(out) :: mass(FE_NDOF, FE_NDOF)
        real(dp), allocatable :: xg(:), wg(:)
        real(dp) :: f2(FE_NDOF)
        integer :: n
        n = fe_quadrature_order(cubic)
        allocate (xg(n), wg(n))
        call fe_gauss_points(n, xg, wg)
        energy = fe_element_energy(h, ea, ei, cubic, xg, wg, qe)
        call fe_element_tangent(h, ea, ei, cubic, xg, wg, qe, force, tangent)
        call fe_element_force(h, ea, ei, cubic, xg, wg, qe, f2)
        call check_close(t, 'force of fe_element_force = of fe_element_tangent', f2, force, &
                         1.0e-14_dp, 1.0e-14_dp*maxval(abs(force)))
        call fe_element_mass(h, rho, mass)
    end subroutine element

    function energy_of(h, ea, ei, cubic, qe) result(v)
        real(dp), intent(in) :: h, ea, ei, cubic, qe(FE_NDOF)
        real(dp) :: v, f(FE_NDOF), k(FE_NDOF, FE_NDOF), m(FE_NDOF, FE_NDOF)
        call element(h, ea, ei, cubic, 0.0_dp, qe, v, f, k, m)
    end function energy_of

    function force_of(h, ea, ei, cubic, qe) result(f)
        real(dp), intent(in) :: h, ea, ei, cubic, qe(FE_NDOF)
        real(dp) :: v, f(FE_NDOF), k(FE_NDOF, FE_NDOF), m(FE_NDOF, FE_NDOF)
        call element(h, ea, ei, cubic, 0.0_dp, qe, v, f, k, m)
    end function force_of

    !> Uniform numbers in [-a, a].
    function uniform(n, a) result(x)
        integer, intent(in) :: n
        real(dp), intent(in) :: a
        real(dp) :: x(n)
        call random_number(x)
        x = a*(2.0_dp*x - 1.0_dp)
    end function uniform

    ! --- the F-tensor form (Eq. 77) -------------------------------------------

    !> Coefficients (ascending powers of zeta = s/h) of the Hermite function
    !! j of Eq. 76, differentiated `order` times in s.
    pure function hermite_poly(j, h, order) result(p)
        integer, intent(in) :: j, order
        real(dp), intent(in) :: h
        real(dp) :: p(0:DEG)
        integer :: o, k
        p = 0.0_dp
        select case (j)
        case (1)
            p(0:3) = [1.0_dp, 0.0_dp, -3.0_dp, 2.0_dp]
        case (2)
            p(0:3) = h*[0.0_dp, 1.0_dp, -2.0_dp, 1.0_dp]
        case (3)
            p(0:3) = [0.0_dp, 0.0_dp, 3.0_dp, -2.0_dp]
        case (4)
            p(0:3) = h*[0.0_dp, 0.0_dp, -1.0_dp, 1.0_dp]
        end select
        do o = 1, order
            do k = 0, DEG - 1
                p(k) = real(k + 1, dp)*p(k + 1)/h
            end do
            p(DEG) = 0.0_dp
        end do
    end function hermite_poly

    pure function poly_mul(a, b) result(c)
        real(dp), intent(in) :: a(0:DEG), b(0:DEG)
        real(dp) :: c(0:DEG)
        integer :: i, j
        c = 0.0_dp
        do i = 0, DEG
            do j = 0, DEG - i
                c(i + j) = c(i + j) + a(i)*b(j)
            end do
        end do
    end function poly_mul

    !> int_0^1 p dzeta.
    pure real(dp) function poly_int(p)
        real(dp), intent(in) :: p(0:DEG)
        integer :: k
        poly_int = 0.0_dp
        do k = 0, DEG
            poly_int = poly_int + p(k)/real(k + 1, dp)
        end do
    end function poly_int

    !> F tensor with derivative orders `orders` contracted with the columns of
    !! `vecs` on all indices but the first (the test function):
    !! c_j = int_0^1 f_j^(o1) prod_i (sum_k vecs(k, i) f_k^(o_{i+1})) dzeta.
    function contract(h, orders, vecs) result(c)
        real(dp), intent(in) :: h
        integer, intent(in) :: orders(:)
        real(dp), intent(in) :: vecs(:, :)
        real(dp) :: c(4), prod(0:DEG), g(0:DEG)
        integer :: j, i, k
        do j = 1, 4
            prod = hermite_poly(j, h, orders(1))
            do i = 1, size(vecs, 2)
                g = 0.0_dp
                do k = 1, 4
                    g = g + vecs(k, i)*hermite_poly(k, h, orders(i + 1))
                end do
                prod = poly_mul(prod, g)
            end do
            c(j) = poly_int(prod)
        end do
    end function contract

    !> Internal force of one element from F tensors (the structure of Eq. 77:
    !! with a = U.f', b = W.f', c = U.f'', d = W.f'', the axial force is
    !! EA e de/dq with e (1 + a) f_k' and e b f_k'; the bending force EI chi
    !! dchi/dq with chi = d + d a - b c, dchi/dU_k = d f_k' - b f_k'',
    !! dchi/dW_k = (1 + a) f_k'' - c f_k').
    function tensor_force(h, ea, ei, qe) result(out)
        real(dp), intent(in) :: h, ea, ei, qe(FE_NDOF)
        real(dp) :: out(FE_NDOF), w(4), u(4), fu(4), fw(4)
        w = qe(FE_W)
        u = qe(FE_U)
        fu = ea*(contract(h, [1, 1], col(u)) + 1.5_dp*contract(h, [1, 1, 1], cols(u, u)) &
                 + 0.5_dp*contract(h, [1, 1, 1], cols(w, w)) &
                 + 0.5_dp*contract(h, [1, 1, 1, 1], cols(u, u, u)) &
                 + 0.5_dp*contract(h, [1, 1, 1, 1], cols(u, w, w)))
        fw = ea*(contract(h, [1, 1, 1], cols(u, w)) &
                 + 0.5_dp*contract(h, [1, 1, 1, 1], cols(u, u, w)) &
                 + 0.5_dp*contract(h, [1, 1, 1, 1], cols(w, w, w)))
        fu = fu + ei*(contract(h, [1, 2, 2], cols(w, w)) &
                      + contract(h, [1, 2, 1, 2], cols(w, u, w)) &
                      - contract(h, [1, 1, 2, 2], cols(w, u, w)) &
                      - contract(h, [2, 2, 1], cols(w, w)) &
                      - contract(h, [2, 2, 1, 1], cols(w, u, w)) &
                      + contract(h, [2, 1, 2, 1], cols(w, u, w)))
        fw = fw + ei*(contract(h, [2, 2], col(w)) + 2.0_dp*contract(h, [2, 2, 1], cols(w, u)) &
                      - contract(h, [1, 2, 2], cols(w, u)) &
                      + contract(h, [2, 2, 1, 1], cols(w, u, u)) &
                      - contract(h, [1, 2, 1, 2], cols(w, u, u)) &
                      - contract(h, [2, 1, 2], cols(w, u)) &
                      - contract(h, [2, 1, 2, 1], cols(w, u, u)) &
                      + contract(h, [1, 1, 2, 2], cols(w, u, u)))
        out(FE_W) = h*fw
        out(FE_U) = h*fu
    end function tensor_force

    pure function col(a) result(m)
        real(dp), intent(in) :: a(4)
        real(dp) :: m(4, 1)
        m(:, 1) = a
    end function col

    pure function cols(a, b, c) result(m)
        real(dp), intent(in) :: a(4), b(4)
        real(dp), intent(in), optional :: c(4)
        real(dp), allocatable :: m(:, :)
        if (present(c)) then
            m = reshape([a, b, c], [4, 3])
        else
            m = reshape([a, b], [4, 2])
        end if
    end function cols

    subroutine f_tensor_form(h, ea, ei)
        real(dp), intent(in) :: h, ea, ei
        real(dp) :: qe(FE_NDOF), got(FE_NDOF), want(FE_NDOF)
        qe = uniform(FE_NDOF, 0.5_dp)
        got = force_of(h, ea, ei, 0.0_dp, qe)
        want = tensor_force(h, ea, ei, qe)
        call check_close(t, 'element force = F-tensor form (Eq. 77)', got, want, 1.0e-11_dp, &
                         1.0e-9_dp*maxval(abs(want)))
    end subroutine f_tensor_form

    ! --- derivatives against central differences ----------------------------

    !> Fourth-order central differences of the energy (gradient) and of the
    !! force (Jacobian): with the cubic moment law on a short element the
    !! second-order stencil's truncation error reaches 1e-6 of the tangent.
    subroutine fd_derivatives(h, ea, ei, cubic, qe, step, grad, jac)
        real(dp), intent(in) :: h, ea, ei, cubic, qe(FE_NDOF), step
        real(dp), intent(out) :: grad(FE_NDOF), jac(FE_NDOF, FE_NDOF)
        real(dp) :: e(FE_NDOF)
        integer :: i
        do i = 1, FE_NDOF
            e = 0.0_dp
            e(i) = step
            grad(i) = (8.0_dp*(energy_of(h, ea, ei, cubic, qe + e) &
                               - energy_of(h, ea, ei, cubic, qe - e)) &
                       - (energy_of(h, ea, ei, cubic, qe + 2*e) &
                          - energy_of(h, ea, ei, cubic, qe - 2*e)))/(12.0_dp*step)
            jac(:, i) = (8.0_dp*(force_of(h, ea, ei, cubic, qe + e) &
                                 - force_of(h, ea, ei, cubic, qe - e)) &
                         - (force_of(h, ea, ei, cubic, qe + 2*e) &
                            - force_of(h, ea, ei, cubic, qe - 2*e)))/(12.0_dp*step)
        end do
    end subroutine fd_derivatives

    subroutine central_differences(h, ea, ei, cubic)
        real(dp), intent(in) :: h, ea, ei, cubic
        real(dp) :: qe(FE_NDOF), v, f(FE_NDOF), k(FE_NDOF, FE_NDOF), m(FE_NDOF, FE_NDOF)
        real(dp) :: grad(FE_NDOF), jac(FE_NDOF, FE_NDOF)
        qe = uniform(FE_NDOF, 0.6_dp)
        call element(h, ea, ei, cubic, 0.0_dp, qe, v, f, k, m)
        call fd_derivatives(h, ea, ei, cubic, qe, 1.0e-6_dp, grad, jac)
        call check_close(t, 'force = central differences of the energy', f, grad, 1.0e-7_dp, &
                         1.0e-7_dp*maxval(abs(f)))
        call check_close(t, 'tangent = central differences of the force', k, jac, 0.0_dp, &
                         1.0e-7_dp*maxval(abs(k)))
        call check_close(t, 'tangent is symmetric', k, transpose(k), 0.0_dp, &
                         1.0e-9_dp*maxval(abs(k)))
    end subroutine central_differences

    !> At random states, lengths and cubic coefficients the tangent is the
    !! central-difference derivative of the force (relative 1e-6).
    subroutine tangent_property(nsample)
        integer, intent(in) :: nsample
        real(dp) :: qe(FE_NDOF), v, f(FE_NDOF), k(FE_NDOF, FE_NDOF), m(FE_NDOF, FE_NDOF)
        real(dp) :: grad(FE_NDOF), jac(FE_NDOF, FE_NDOF), r(2), h, cubic
        integer :: s
        do s = 1, nsample
            qe = uniform(FE_NDOF, 0.6_dp)
            call random_number(r)
            h = 0.05_dp + 0.95_dp*r(1)
            cubic = 20.0_dp*r(2)
            call element(h, 1.0e4_dp, 10.0_dp, cubic, 0.0_dp, qe, v, f, k, m)
            call fd_derivatives(h, 1.0e4_dp, 10.0_dp, cubic, qe, 1.0e-6_dp, grad, jac)
            call check_close(t, 'tangent = central differences (random element)', k, jac, &
                             0.0_dp, 1.0e-6_dp*max(maxval(abs(k)), 1.0_dp))
        end do
    end subroutine tangent_property

    ! --- mass ------------------------------------------------------------------

    subroutine mass_integrates_exactly()
        real(dp), parameter :: h = 0.37_dp, rho = 0.53_dp
        real(dp) :: v, f(FE_NDOF), k(FE_NDOF, FE_NDOF), m(FE_NDOF, FE_NDOF)
        real(dp) :: one(FE_NDOF), ramp(FE_NDOF), zero8(FE_NDOF)
        zero8 = 0.0_dp
        call element(h, 1.0_dp, 1.0_dp, 0.0_dp, rho, zero8, v, f, k, m)
        one = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]   ! w = 1
        ramp = [0.0_dp, 1.0_dp, 0.0_dp, 0.0_dp, h, 1.0_dp, 0.0_dp, 0.0_dp]      ! w = s
        call check_close(t, 'mass: int rho ds', dot_product(one, matmul(m, one)), rho*h, &
                         1.0e-14_dp, 0.0_dp)
        call check_close(t, 'mass: int rho s^2 ds', dot_product(ramp, matmul(m, ramp)), &
                         rho*h**3/3, 1.0e-14_dp, 0.0_dp)
        call check_close(t, 'mass: int rho s ds', dot_product(one, matmul(m, ramp)), &
                         rho*h**2/2, 1.0e-14_dp, 0.0_dp)
        call check_close(t, 'mass is symmetric', m, transpose(m), 1.0e-15_dp, 0.0_dp)
    end subroutine mass_integrates_exactly

    ! --- the reduced element (f1 + f3 = 1, Eq. 76) ----------------------------

    subroutine rigid_translation(h, ea, ei, cubic)
        real(dp), intent(in) :: h, ea, ei, cubic
        real(dp), parameter :: shift(FE_NDOF) = [0.7_dp, 0.0_dp, -0.4_dp, 0.0_dp, 0.7_dp, &
                                                 0.0_dp, -0.4_dp, 0.0_dp]
        real(dp) :: qe(FE_NDOF), v, f(FE_NDOF), k(FE_NDOF, FE_NDOF), m(FE_NDOF, FE_NDOF)
        real(dp) :: v2, f2(FE_NDOF), k2(FE_NDOF, FE_NDOF)
        qe = uniform(FE_NDOF, 0.5_dp)
        call element(h, ea, ei, cubic, 0.0_dp, qe, v, f, k, m)
        call element(h, ea, ei, cubic, 0.0_dp, qe + shift, v2, f2, k2, m)
        call check_close(t, 'rigid translation: energy', v2, v, 1.0e-11_dp, 0.0_dp)
        call check_close(t, 'rigid translation: force', f2, f, 0.0_dp, &
                         1.0e-10_dp*maxval(abs(f)))
        call check_close(t, 'rigid translation: tangent', k2, k, 0.0_dp, &
                         1.0e-10_dp*maxval(abs(k)))
    end subroutine rigid_translation

    !> The energy gradient along a rigid translation is zero (central
    !! differences of the energy): f_w1 + f_w2 = 0 and f_u1 + f_u2 = 0.
    subroutine node_two_mirrors_node_one(h, ea, ei, cubic)
        real(dp), intent(in) :: h, ea, ei, cubic
        real(dp), parameter :: step = 1.0e-6_dp
        integer, parameter :: pairs(2, 2) = reshape([1, 5, 3, 7], [2, 2])
        real(dp) :: qe(FE_NDOF), v, f(FE_NDOF), k(FE_NDOF, FE_NDOF), m(FE_NDOF, FE_NDOF)
        real(dp) :: e(FE_NDOF), slope, scale
        integer :: p
        qe = uniform(FE_NDOF, 0.5_dp)
        call element(h, ea, ei, cubic, 0.0_dp, qe, v, f, k, m)
        scale = maxval(abs(f))
        do p = 1, 2
            e = 0.0_dp
            e(pairs(:, p)) = step
            slope = (energy_of(h, ea, ei, cubic, qe + e) - energy_of(h, ea, ei, cubic, qe - e)) &
                    /(2.0_dp*step)
            call check_close(t, 'energy is flat along a rigid translation', slope, 0.0_dp, &
                             0.0_dp, 1.0e-7_dp*scale)
            call check_close(t, 'node-2 force mirrors node 1', f(pairs(2, p)), -f(pairs(1, p)), &
                             0.0_dp, 1.0e-12_dp*scale)
        end do
    end subroutine node_two_mirrors_node_one

    ! --- assembly ----------------------------------------------------------------

    !> The banded tangent of the PACE chain with a hinged elbow, a root hinge
    !! and the cubic moment law (every path of fe_tangent: consecutive
    !! elements, the clamp, the hinges' springs) against central differences
    !! of fe_internal_force; f of fe_tangent is fe_internal_force; a work
    !! type (fe_work_init) gives the same numbers as the calls without one.
    subroutine assembled_tangent()
        type(chain_t) :: chain
        type(fe_mesh_t) :: mesh
        type(fe_work_t) :: work
        type(status_t) :: stat
        real(dp), allocatable :: params(:), q(:), f(:), f0(:), kb(:, :), k(:, :), jac(:, :)
        real(dp), allocatable :: e(:), fp(:), fm(:)
        real(dp), parameter :: step = 1.0e-6_dp
        integer :: nb, i, n
        call preset_params('pace', nb, params, stat)
        call check_true(t, 'pace preset', stat%code == STATUS_OK)
        do i = 1, size(params)
            select case (param_name(nb, i))
            case ('C1')
                params(i) = 3.0_dp
            case ('C2')
                params(i) = 1.0_dp
            case ('elbow_flex')
                params(i) = 0.01_dp
            case ('root_flex')
                params(i) = 0.02_dp
            end select
        end do
        call chain_from_vector(nb, params, chain, stat)
        if (stat%code == STATUS_OK) call fe_mesh_build(chain, 3, mesh, stat)
        call check_true(t, 'hinged PACE mesh: '//trim(stat%message), stat%code == STATUS_OK)
        if (stat%code /= STATUS_OK) return
        call check_true(t, 'the mesh has a hinge and a root hinge', &
                        mesh%nhinge == 1 .and. mesh%root_flex > 0.0_dp)
        n = mesh%nfree
        allocate (q(n), f(n), f0(n), kb(fe_band_rows(mesh), n), k(n, n), jac(n, n), e(n), &
                  fp(n), fm(n))
        q = uniform(n, 0.2_dp)
        call fe_tangent(mesh, q, f, kb)
        call fe_internal_force(mesh, q, f0)
        call check_close(t, 'fe_tangent force = fe_internal_force', f, f0, 1.0e-13_dp, &
                         1.0e-13_dp*maxval(abs(f0)))
        call band_to_dense(kb, mesh%kl, mesh%ku, k)
        do i = 1, n
            e = 0.0_dp
            e(i) = step
            call fe_internal_force(mesh, q + e, fp)
            call fe_internal_force(mesh, q - e, fm)
            jac(:, i) = (fp - fm)/(2.0_dp*step)
        end do
        call check_close(t, 'assembled tangent = central differences', k, jac, 0.0_dp, &
                         1.0e-7_dp*maxval(abs(k)))
        call fe_work_init(mesh, work)
        call fe_tangent(mesh, q, fp, kb, work)
        call band_to_dense(kb, mesh%kl, mesh%ku, jac)
        call check_close(t, 'fe_tangent with a work type', [fp, reshape(jac, [n*n])], &
                         [f, reshape(k, [n*n])], 0.0_dp, 0.0_dp)
        call fe_internal_force(mesh, q, fm, work)
        call check_close(t, 'fe_internal_force with a work type', fm, f0, 0.0_dp, 0.0_dp)
    end subroutine assembled_tangent
end program test_fe_element
