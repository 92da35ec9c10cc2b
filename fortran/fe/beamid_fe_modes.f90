!> Linear natural modes of the finite element chain and Skelton's modal cost.
!!
!! The linear model is the tangent of the nonlinear element at the straight
!! chain (Eq. 123-124): K phi = omega^2 M phi, solved with LAPACK dsygv, which
!! returns mass-normalized modes phi^T M phi = 1 and phi^T K phi = omega^2
!! (Eq. 125-126). At the straight chain u and w decouple, so every mode is
!! either transverse (w) or axial (u): Tables 9 and 10.
module beamid_fe_modes
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_INPUT, ERR_NUMERIC, fmt_int, &
                             fmt_real, set_alloc_error
    use beamid_lapack, only: sym_gen_eig
    use beamid_fe_assembly, only: fe_mesh_t, fe_check_dense, fe_band_rows, fe_mass, &
                                  fe_stiffness_linear, DOF_U, DOF_DU, &
                                  DOF_DU_OUT
    use beamid_band, only: band_mv, band_to_dense
    implicit none
    private

    public :: fe_modes, fe_modal_coordinates, fe_modal_cost, fe_is_axial_unknown
    public :: fe_axial_modes_linear

contains

    !> True when free unknown `k` is an axial one (u, u', or a hinge's u'+).
    pure logical function fe_is_axial_unknown(mesh, k)
        type(fe_mesh_t), intent(in) :: mesh
        integer, intent(in) :: k
        integer :: comp
        comp = mesh%free_comp(k)
        fe_is_axial_unknown = comp == DOF_U .or. comp == DOF_DU .or. comp == DOF_DU_OUT
    end function fe_is_axial_unknown

    !> Natural frequencies omega (rad/s, ascending), mass-normalized mode shapes
    !! phi (columns, free unknowns) and the family of each mode (axial = .true.
    !! when most of its modal mass phi^T M phi lies on the u unknowns).
    !! `rotary` adds the rotary inertia of the point masses (Eq. 130-132).
    subroutine fe_modes(mesh, rotary, omega, phi, axial, stat)
        type(fe_mesh_t), intent(in) :: mesh
        logical, intent(in) :: rotary
        real(dp), intent(out) :: omega(:), phi(:, :)
        logical, intent(out) :: axial(:)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: kb(:, :), mb(:, :), m(:, :), w(:), q0(:), mphi(:)
        real(dp) :: mu
        integer :: n, i, k, ierr
        n = mesh%nfree
        if (size(omega) /= n .or. any(shape(phi) /= [n, n]) .or. size(axial) /= n) then
            call set_status(stat, ERR_INPUT, 'fe_modes', 'output sizes do not match '// &
                            'nfree = '//fmt_int(n))
            return
        end if
        call fe_check_dense(n, 'fe_modes', stat)
        if (stat%code /= 0) return
        allocate (kb(fe_band_rows(mesh), n), mb(fe_band_rows(mesh), n), m(n, n), w(n), &
                  q0(n), mphi(n), source=0.0_dp, stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(stat, 'fe_modes', 'the mode matrices', &
                                 8.0_dp*3.0_dp*real(n, dp)**2)
            return
        end if
        call fe_stiffness_linear(mesh, kb)
        call fe_mass(mesh, q0, rotary, mb)
        call band_to_dense(kb, mesh%kl, mesh%ku, phi)
        call band_to_dense(mb, mesh%kl, mesh%ku, m)
        call sym_gen_eig(phi, m, w, stat)
        if (stat%code /= 0) return
        if (any(w <= 0.0_dp)) then
            call set_status(stat, ERR_NUMERIC, 'fe_modes', 'non-positive eigenvalue '// &
                            fmt_real(minval(w))//': the stiffness is not positive definite')
            return
        end if
        omega = sqrt(w)
        do i = 1, n
            call band_mv(mb, mesh%kl, mesh%ku, phi(:, i), mphi)
            mu = 0.0_dp
            do k = 1, n
                if (fe_is_axial_unknown(mesh, k)) mu = mu + phi(k, i)*mphi(k)
            end do
            ! mu is the axial share of phi^T M phi = 1 (exactly 0 or 1 at q = 0
            ! unless rotary inertia couples u' and w', which it does not at q = 0)
            axial(i) = mu > 0.5_dp
        end do
    end subroutine fe_modes

    !> Modal coordinates eta = Phi^T M q of a shape q (the inverse of q = Phi eta
    !! for mass-normalized modes, Eq. 116 and 127).
    subroutine fe_modal_coordinates(mesh, rotary, phi, q, eta, stat)
        type(fe_mesh_t), intent(in) :: mesh
        logical, intent(in) :: rotary
        real(dp), intent(in) :: phi(:, :), q(:)
        real(dp), intent(out) :: eta(:)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: mb(:, :), mq(:), q0(:)
        integer :: n
        n = mesh%nfree
        if (any(shape(phi) /= [n, n]) .or. size(q) /= n .or. size(eta) /= n) then
            call set_status(stat, ERR_INPUT, 'fe_modal_coordinates', 'sizes do not '// &
                            'match nfree = '//fmt_int(n))
            return
        end if
        allocate (mb(fe_band_rows(mesh), n), mq(n), q0(n), source=0.0_dp)
        call fe_mass(mesh, q0, rotary, mb)
        call band_mv(mb, mesh%kl, mesh%ku, q, mq)
        eta = matmul(mq, phi)
    end subroutine fe_modal_coordinates

    !> Skelton's modal cost (Eq. 128) for the linear free vibration in modal
    !! coordinates from eta(0) = eta0, eta'(0) = etadot0 over [0, t]:
    !! kinetic(i) = int eta_i'^2 dt and potential(i) = int omega_i^2 eta_i^2 dt
    !! in closed form; their sum omega^2 eta0^2 t + etadot0^2 t ranks the modes.
    pure subroutine fe_modal_cost(omega, eta0, etadot0, t, kinetic, potential)
        real(dp), intent(in) :: omega(:), eta0(:), etadot0(:), t
        real(dp), intent(out) :: kinetic(:), potential(:)
        real(dp) :: a, b, w, icc, iss, ics
        integer :: i
        do i = 1, size(omega)
            w = omega(i)
            a = eta0(i)
            b = etadot0(i)/w
            icc = 0.5_dp*t + sin(2.0_dp*w*t)/(4.0_dp*w)
            iss = 0.5_dp*t - sin(2.0_dp*w*t)/(4.0_dp*w)
            ics = sin(w*t)**2/(2.0_dp*w)
            potential(i) = w*w*(a*a*icc + 2.0_dp*a*b*ics + b*b*iss)
            kinetic(i) = w*w*(a*a*iss - 2.0_dp*a*b*ics + b*b*icc)
        end do
    end subroutine fe_modal_cost

    !> Axial frequencies of the linear verification model of Eq. 112-115: u
    !! with the linear shape functions of Eq. 114 (one unknown per node, u = 0
    !! at the root), consistent mass rho h/6 [2 1; 1 2]. With point_masses the
    !! joint and tip masses are added to the axial mass. Table 7's axial column
    !! is this model *without* the point masses, from its second frequency on
    !! (see docs/deviations.md). omega has nel entries, ascending.
    subroutine fe_axial_modes_linear(mesh, point_masses, omega, stat)
        type(fe_mesh_t), intent(in) :: mesh
        logical, intent(in) :: point_masses
        real(dp), intent(out) :: omega(:)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: k(:, :), m(:, :), w(:)
        real(dp) :: ke, me
        integer :: n, el, i, j, ierr
        n = mesh%nel
        if (size(omega) /= n) then
            call set_status(stat, ERR_INPUT, 'fe_axial_modes_linear', 'omega has '// &
                            fmt_int(size(omega))//' entries, expected '//fmt_int(n))
            return
        end if
        call fe_check_dense(n, 'fe_axial_modes_linear', stat)
        if (stat%code /= 0) return
        ! unknown i is u at node i + 1
        allocate (k(n, n), m(n, n), w(n), source=0.0_dp, stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(stat, 'fe_axial_modes_linear', 'the mode matrices', &
                                 8.0_dp*2.0_dp*real(n, dp)**2)
            return
        end if
        do el = 1, n
            ke = mesh%ea(el)/mesh%h(el)
            me = mesh%rho(el)*mesh%h(el)/6.0_dp
            i = el - 1
            j = el
            k(j, j) = k(j, j) + ke
            m(j, j) = m(j, j) + 2.0_dp*me
            if (i >= 1) then
                k(i, i) = k(i, i) + ke
                k(i, j) = k(i, j) - ke
                k(j, i) = k(j, i) - ke
                m(i, i) = m(i, i) + 2.0_dp*me
                m(i, j) = m(i, j) + me
                m(j, i) = m(j, i) + me
            end if
        end do
        if (point_masses) then
            do i = 1, n
                m(i, i) = m(i, i) + mesh%node_mass(i + 1)
            end do
        end if
        call sym_gen_eig(k, m, w, stat)
        if (stat%code /= 0) return
        omega = sqrt(max(w, 0.0_dp))
    end subroutine fe_axial_modes_linear

end module beamid_fe_modes
