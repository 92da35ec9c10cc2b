!> Nonlinear finite element dynamics of the beam chain (Chapter IV-V):
!! the equations of motion M(q) q'' + NLT(q) = Q(q, q') of Eq. 98 with the
!! clamped root eliminated (Eq. 103-107), the named nonconservative effects,
!! their hand-coded Jacobians and the energy ledger.
!!
!! State: the free unknowns q (the order of beamid_fe_assembly), their rates
!! v = q', and, when the motor has a current-loop lag, the motor torque T.
!! Generalized force (everything but the inertia) F(q, v, T):
!!
!!     F = -NLT(q) - g_rot(q, v) + Q_fr(v) + Q_drag(v) - D(q) v + T a_tip(q)
!!
!! - NLT: internal force of the Epstein-Murray elements (Eq. 79-83, 87).
!! - Coulomb friction per Cartesian component at each mass point (Eq. 100-102),
!!   -mu m g phi(v): phi = sign(v) with sign(0) = 0 (FRICTION_SIGN), the
!!   literal Fortran port SIGN(1, v) = +1 at v = 0 (FRICTION_SIGN_LITERAL),
!!   or the regularization phi = v / sqrt(v^2 + vs^2) (FRICTION_SMOOTH).
!! - Viscous drag -c v on u and w of each mass point.
!! - Kelvin-Voigt structural damping: bending moment += eta EI dchi/dt, whose
!!   generalized force is D(q) v with D = eta int EI dchi/dq dchi/dq^T ds.
!! - Rotary inertia J of the mass points (Eq. 130-132): J a a^T enters M(q)
!!   (fe_mass), the velocity term g_rot = 2 J Psidot (u'_t, -w'_t) on (w', u').
!!   Eq. 132 prints +2 w'_t Psidot in the u' row; Lagrange's equations give the
!!   minus sign (docs/theory_dynamics.md), and energy conservation confirms it.
!! - Tip reaction-wheel motor (Eq. 150-159): T = -r g Psidot_tip, acting as
!!   T delta Psi_tip = T [(1 + u') delta w' - w' delta u'] (Eq. 151-152); with
!!   a current-loop lag tau: tau T' = -r g Psidot - T.
!! Psidot = (1 + u') w'_t - w' u'_t (Eq. 153), a = (1 + u', -w') on (w', u').
!!
!! Ledger (Eq. 118-122, 155-156): kinetic energy v^T M(q) v / 2 (Eq. 119),
!! strain energy V (Eq. 87), and the work of each effect, integrated from its
!! power along the trajectory. Work lines, npt = nbeams mass points:
!! 1..npt friction at point k, npt+1..2 npt drag at point k, 2 npt + 1
!! structural damping, 2 npt + 2 motor.
module beamid_dynamics
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use beamid_kinds, only: dp, GRAVITY => g_standard
    use beamid_status, only: status_t, set_status, ERR_INPUT, ERR_SINGULAR, fmt_int, &
                             fmt_real
    use beamid_model, only: chain_t, param_name, PER_BEAM, PER_MASS, IB_EI, IB_EA, IB_RHO, &
                            IB_C, IM_M, IM_J, IM_MU, IM_C, IG_ROOT_FLEX, IG_ETA, IG_R_MOTOR, &
                            IG_TAU_MOTOR
    use beamid_fe_element, only: FE_NDOF, FE_W, FE_U, fe_hermite, fe_element_mass, &
                                 fe_element_force_tabulated, fe_element_energy, &
                                 fe_hinge_force, fe_hinge_energy
    use beamid_fe_assembly, only: fe_mesh_t, fe_mesh_build, fe_band_rows, fe_band_add, &
                                  fe_internal_force, fe_tangent, fe_energy, fe_mass, &
                                  fe_band_matvec, fe_expand, DOF_W, DOF_DW, DOF_U, DOF_DU, &
                                  fe_load_t, fe_tip_load, fe_spring_dofs
    use beamid_fe_static, only: fe_residual
    use beamid_lapack, only: solve_banded
    use beamid_band, only: band_lu_t, band_factor, band_solve
    use beamid_fe_modes, only: fe_modes
    use beamid_forcing, only: forcing_t, forcing_slot_t
    implicit none
    private

    public :: dyn_system_t, dyn_setup, dyn_forces, dyn_power, dyn_jacobian, dyn_rates, dyn_energy
    public :: dyn_velocity_coupled, dyn_damping_dir
    public :: dyn_mass, dyn_tip, dyn_nwork, dyn_psidot, dyn_torque
    public :: FRICTION_SIGN, FRICTION_SMOOTH, FRICTION_SIGN_LITERAL, GRAVITY
    public :: dyn_set_modes, dyn_to_physical, dyn_to_coords, dyn_cforces, dyn_cpower
    public :: dyn_cxrate, dyn_cmass, dyn_cjacobian, dyn_crates
    public :: dyn_hold, dyn_switch, dyn_rot_mv, dyn_fric_dof
    public :: dyn_param_t, dyn_param_setup, dyn_dforce, dyn_dmass_mv, dyn_dmass_dq_mv
    public :: dyn_static_sens, dyn_output_sens, dyn_constrain, dyn_denergy, dyn_dnlt
    public :: DP_NONE, DP_LOAD, DP_FORCING, dyn_param_dcap
    public :: damping_element
    public :: dyn_eval, dyn_add_forcing, dyn_work_name, dyn_breakpoints, dyn_dbreak

    !> Kinds of parameter derivatives (dyn_param_t): what a parameter acts on.
    integer, parameter :: DP_NONE = 0, DP_EI = 1, DP_EA = 2, DP_CUBIC = 3, DP_RHO = 4, &
                          DP_MASS = 5, DP_J = 6, DP_MU = 7, DP_DRAG = 8, DP_ETA = 9, &
                          DP_R = 10, DP_TAU = 11, DP_FLEX = 12, DP_LOAD = 13, &
                          DP_FORCING = 14

    !> One parameter of a sensitivity: its kind (DP_*), the beam, mass point,
    !! joint or load component it belongs to, the constant dM/dp (density,
    !! point mass), d(mu m g)/dp (friction cap) and the spring (0: root).
    !! DP_FORCING: parameter ip of forcing k (sys%loads(k)).
    type :: dyn_param_t
        integer :: kind = DP_NONE
        integer :: k = 0
        integer :: ip = 0
        integer :: spring = -1
        real(dp) :: dcap = 0.0_dp
        real(dp), allocatable :: dmb(:, :)
    end type dyn_param_t

    !> Friction laws (Eq. 101-102 and the regularized form for implicit steps).
    integer, parameter :: FRICTION_SIGN = 0, FRICTION_SMOOTH = 1, FRICTION_SIGN_LITERAL = 2
    ! GRAVITY (exported) is beamid_kinds g_standard, N = m g of Eq. 101 (m/s^2).


    !> The discretized chain with its effects, ready for time integration.
    type :: dyn_system_t
        type(fe_mesh_t) :: mesh
        integer :: n = 0            !< free unknowns (q and v each)
        integer :: nx = 0           !< extra states: 1 with a motor lag, else 0
        integer :: nstate = 0       !< 2 n + nx
        integer :: npt = 0          !< mass points (joints and tip)
        integer :: nwork = 0        !< work lines (2 npt + 2 + nloads)
        !> forcings in time (beamid_forcing): work line 2 npt + 2 + l is load l's
        integer :: nloads = 0
        type(forcing_slot_t), allocatable :: loads(:)
        integer, allocatable :: iw(:), iu(:), idw(:), idu(:)   !< free indices per point
        real(dp), allocatable :: fric(:)    !< mu m g per point (N)
        real(dp), allocatable :: drag(:)    !< c per point (N s/m)
        real(dp), allocatable :: inertia(:) !< J per point (kg m^2)
        logical :: rotary = .false.
        real(dp) :: eta = 0.0_dp
        real(dp) :: motor = 0.0_dp          !< r g (N m s)
        real(dp) :: gain = 0.0_dp           !< motor gain g (Eq. 150)
        real(dp) :: tau = 0.0_dp            !< motor lag (s)
        integer :: law = FRICTION_SIGN
        real(dp) :: vslip = 1.0e-4_dp       !< regularization velocity (m/s)
        !> Friction switching as events (the sign law, Eq. 101-102, in the
        !! integrators): component j = 2 (k - 1) + c of mass point k (c = 1: u,
        !! c = 2: w) slides with the discrete sign fmode(j) = +-1 (friction
        !! -mu N fmode(j), smooth between events), or sticks (fmode(j) = 0:
        !! its velocity held at 0 by a constraint force, dyn_hold). Off
        !! (events = .false.), the sign law takes sign(v) at every evaluation.
        logical :: events = .false.
        integer, allocatable :: fmode(:)
        !> M^-1 e_i for the free index i of each friction component (constant
        !! mass matrix only; columns of zero friction unused)
        real(dp), allocatable :: minvf(:, :)
        !> constant mass matrix (band) and its factors; unused when rotary
        real(dp), allocatable :: mb(:, :)
        type(band_lu_t) :: mlu
        !> integration coordinates: nc = n (the free unknowns) or the number of
        !! retained modes; their state length 2 nc + nx and band half-widths
        integer :: nc = 0, ncstate = 0, ckl = 0, cku = 0
        logical :: modal = .false.            !< truncated modal model (Eq. 127)
        real(dp), allocatable :: phi(:, :)    !< retained modes, n x nc (Eq. 125)
        real(dp), allocatable :: omega_r(:)   !< their frequencies (rad/s)
        real(dp), allocatable :: cmb(:, :)    !< Phi^T M(0) Phi (band, ckl = cku)
        type(band_lu_t) :: cmlu               !< its factors
    end type dyn_system_t

contains

    !> Number of work lines of a chain of `nbeams` beams.
    pure integer function dyn_nwork(nbeams)
        integer, intent(in) :: nbeams
        dyn_nwork = 2*nbeams + 2
    end function dyn_nwork


    !> Build the dynamic system of `chain` on `elements_per_beam` elements per
    !! beam. `gain` is the motor gain g of Eq. 150 (0: no motor), `law` the
    !! friction law and `vslip` its regularization velocity (FRICTION_SMOOTH).
    subroutine dyn_setup(chain, elements_per_beam, gain, law, vslip, sys, stat)
        type(chain_t), intent(in) :: chain
        integer, intent(in) :: elements_per_beam, law
        real(dp), intent(in) :: gain, vslip
        type(dyn_system_t), intent(out) :: sys
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'dyn_setup'
        real(dp), allocatable :: q0(:)
        integer :: k, node, base
        if (.not. ieee_is_finite(gain) .or. gain < 0.0_dp) then
            call set_status(stat, ERR_INPUT, where, 'motor_gain = '//fmt_real(gain)// &
                            ', expected a finite number >= 0')
            return
        end if
        if (law /= FRICTION_SIGN .and. law /= FRICTION_SMOOTH .and. &
            law /= FRICTION_SIGN_LITERAL) then
            call set_status(stat, ERR_INPUT, where, 'friction law = '//fmt_int(law)// &
                            ', expected 0 (sign), 1 (smooth) or 2 (literal sign)')
            return
        end if
        if (law == FRICTION_SMOOTH .and. .not. (vslip > 0.0_dp .and. ieee_is_finite(vslip))) then
            call set_status(stat, ERR_INPUT, where, 'friction_velocity = '// &
                            fmt_real(vslip)//', expected a positive number')
            return
        end if
        call fe_mesh_build(chain, elements_per_beam, sys%mesh, stat)
        if (stat%code /= 0) return
        sys%n = sys%mesh%nfree
        sys%npt = chain%nbeams
        sys%nwork = dyn_nwork(chain%nbeams)
        allocate (sys%iw(sys%npt), sys%iu(sys%npt), sys%idw(sys%npt), sys%idu(sys%npt), &
                  sys%fric(sys%npt), sys%drag(sys%npt), sys%inertia(sys%npt))
        do k = 1, sys%npt
            node = k*elements_per_beam + 1
            base = 4*(node - 1)
            sys%iw(k) = sys%mesh%free_of(base + DOF_W)
            sys%idw(k) = sys%mesh%free_of(base + DOF_DW)
            sys%iu(k) = sys%mesh%free_of(base + DOF_U)
            sys%idu(k) = sys%mesh%free_of(base + DOF_DU)
            sys%fric(k) = chain%friction(k)*chain%mass(k)*GRAVITY
            sys%drag(k) = chain%drag(k)
            sys%inertia(k) = chain%inertia(k)
        end do
        sys%rotary = any(sys%inertia /= 0.0_dp)
        sys%eta = chain%eta
        sys%motor = chain%r_motor*gain
        sys%gain = gain
        sys%tau = chain%tau_motor
        sys%nx = 0
        if (sys%motor /= 0.0_dp .and. sys%tau > 0.0_dp) sys%nx = 1
        sys%nstate = 2*sys%n + sys%nx
        sys%nc = sys%n
        sys%ncstate = sys%nstate
        sys%ckl = sys%mesh%kl
        sys%cku = sys%mesh%ku
        sys%law = law
        sys%vslip = vslip
        allocate (q0(sys%n), sys%mb(fe_band_rows(sys%mesh), sys%n), source=0.0_dp, stat=k)
        if (k /= 0) then
            call set_status(stat, ERR_INPUT, where, 'cannot allocate the mass matrix of '// &
                            fmt_int(sys%n)//' unknowns')
            return
        end if
        call fe_mass(sys%mesh, q0, .false., sys%mb)
        allocate (sys%fmode(2*sys%npt))
        sys%fmode = 0
        if (.not. sys%rotary) then
            sys%mlu%n = sys%n
            sys%mlu%kl = sys%mesh%kl
            sys%mlu%ku = sys%mesh%ku
            sys%mlu%ab = sys%mb
            call band_factor(sys%mlu, stat)
            if (stat%code /= 0) return
            allocate (sys%minvf(sys%n, 2*sys%npt), stat=k)
            if (k /= 0) then
                call set_status(stat, ERR_INPUT, where, 'cannot allocate M^-1 of the '// &
                                'friction components ('//fmt_int(sys%n)//' unknowns)')
                return
            end if
            sys%minvf = 0.0_dp
            do k = 1, 2*sys%npt
                sys%minvf(dyn_fric_dof(sys, k), k) = 1.0_dp
                call band_solve(sys%mlu, sys%minvf(:, k))
            end do
        end if
    end subroutine dyn_setup

    !> Free index of friction component j = 2 (k - 1) + c (point k, c = 1: u,
    !! c = 2: w).
    pure integer function dyn_fric_dof(sys, j) result(i)
        type(dyn_system_t), intent(in) :: sys
        integer, intent(in) :: j
        integer :: k
        k = (j + 1)/2
        if (mod(j, 2) == 1) then
            i = sys%iu(k)
        else
            i = sys%iw(k)
        end if
    end function dyn_fric_dof

    !> y = y + R(q) x, R(q) = sum_k J_k a_k a_k^T the rotary inertia part of
    !! M(q) (Eq. 130-132) on the slopes (w', u') of each mass point, a_k =
    !! (1 + u', -w'): M(q) = M_c + R(q) with the constant M_c of sys%mb.
    pure subroutine dyn_rot_mv(sys, q, x, y)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: q(:), x(:)
        real(dp), intent(inout) :: y(:)
        real(dp) :: a1, a2, s
        integer :: k
        do k = 1, sys%npt
            if (sys%inertia(k) == 0.0_dp) cycle
            a1 = 1.0_dp + q(sys%idu(k))
            a2 = -q(sys%idw(k))
            s = sys%inertia(k)*(a1*x(sys%idw(k)) + a2*x(sys%idu(k)))
            y(sys%idw(k)) = y(sys%idw(k)) + s*a1
            y(sys%idu(k)) = y(sys%idu(k)) + s*a2
        end do
    end subroutine dyn_rot_mv

    !> Constrain the accelerations a = M^-1 F (in place) of the sticking
    !! friction components (fmode = 0, events on) to zero: a <- a + M^-1 E l
    !! with (E^T M^-1 E) l = -E^T a. hold(j) = l_j is the constraint force
    !! (the friction that holds component j at rest; 0 for the others).
    !! `lu` holds the factors of M (the constant sys%mlu or M(q)).
    subroutine constrain_rates(sys, lu, a, hold, stat)
        type(dyn_system_t), intent(in) :: sys
        type(band_lu_t), intent(in) :: lu
        real(dp), intent(inout) :: a(:)
        real(dp), intent(out) :: hold(:)
        type(status_t), intent(inout) :: stat
        integer :: st(2*sys%npt), ns, j, i
        real(dp), allocatable :: cols(:, :)
        real(dp) :: g(2*sys%npt, 2*sys%npt), l(2*sys%npt)
        hold = 0.0_dp
        if (.not. sys%events) return
        ns = 0
        do j = 1, 2*sys%npt
            if (sys%fric((j + 1)/2) /= 0.0_dp .and. sys%fmode(j) == 0) then
                ns = ns + 1
                st(ns) = j
            end if
        end do
        if (ns == 0) return
        allocate (cols(sys%n, ns))
        do j = 1, ns
            if (sys%rotary) then
                cols(:, j) = 0.0_dp
                cols(dyn_fric_dof(sys, st(j)), j) = 1.0_dp
                call band_solve(lu, cols(:, j))
            else
                cols(:, j) = sys%minvf(:, st(j))
            end if
        end do
        do j = 1, ns
            do i = 1, ns
                g(i, j) = cols(dyn_fric_dof(sys, st(i)), j)
            end do
            l(j) = -a(dyn_fric_dof(sys, st(j)))
        end do
        call small_solve(ns, g(1:ns, 1:ns), l(1:ns), stat)
        if (stat%code /= 0) return
        do j = 1, ns
            a = a + l(j)*cols(:, j)
            hold(st(j)) = l(j)
        end do
        ! exactly at rest
        do j = 1, ns
            a(dyn_fric_dof(sys, st(j))) = 0.0_dp
        end do
    end subroutine constrain_rates

    !> Solve the small dense system g x = b (Gaussian elimination with
    !! partial pivoting), b overwritten by x.
    subroutine small_solve(m, g, b, stat)
        integer, intent(in) :: m
        real(dp), intent(inout) :: g(m, m), b(m)
        type(status_t), intent(inout) :: stat
        integer :: i, j, p
        real(dp) :: t, row(m)
        do j = 1, m
            p = j - 1 + maxloc(abs(g(j:m, j)), 1)
            if (g(p, j) == 0.0_dp) then
                call set_status(stat, ERR_SINGULAR, 'constrain_rates', &
                                'singular constraint matrix of the sticking components')
                return
            end if
            if (p /= j) then
                row = g(j, :)
                g(j, :) = g(p, :)
                g(p, :) = row
                t = b(j)
                b(j) = b(p)
                b(p) = t
            end if
            do i = j + 1, m
                t = g(i, j)/g(j, j)
                g(i, j:m) = g(i, j:m) - t*g(j, j:m)
                b(i) = b(i) - t*b(j)
            end do
        end do
        do j = m, 1, -1
            b(j) = (b(j) - dot_product(g(j, j + 1:m), b(j + 1:m)))/g(j, j)
        end do
    end subroutine small_solve

    !> Constraint forces `hold` of the sticking friction components at the
    !! state y (full model; dyn_rates with the current modes).
    subroutine dyn_hold(sys, t, y, hold, stat)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t           !< time (s): the forcings'
        real(dp), intent(in) :: y(:)
        real(dp), intent(out) :: hold(:)
        type(status_t), intent(inout) :: stat
        real(dp) :: dy(size(y)), power(sys%nwork), torque
        call dyn_rates(sys, t, y, dy, power, torque, stat, hold)
    end subroutine dyn_hold

    !> Friction switching at a state where friction components are at rest
    !! (Eq. 101-102 as events): every tracked component with zero velocity
    !! is first held (fmode = 0); then, as long as some held component needs
    !! a constraint force above its mu N, the one with the largest excess is
    !! released to slide the way the other forces push it (fmode =
    !! -sign(hold)), and the forces are recomputed. `force_release` (0: none)
    !! is a component that leaves the stick now (its |hold| reached mu N).
    !! On return `hold` are the constraint forces of the components that stay.
    subroutine dyn_switch(sys, t, y, force_release, hold, stat)
        type(dyn_system_t), intent(inout) :: sys
        real(dp), intent(in) :: t           !< time (s): the forcings'
        real(dp), intent(in) :: y(:)
        integer, intent(in) :: force_release
        real(dp), intent(out) :: hold(:)
        type(status_t), intent(inout) :: stat
        integer :: j, jmax, pass
        real(dp) :: excess, emax, hsave(2*sys%npt)
        hold = 0.0_dp
        if (.not. sys%events) return
        do j = 1, 2*sys%npt
            if (sys%fric((j + 1)/2) == 0.0_dp) cycle
            if (y(sys%n + dyn_fric_dof(sys, j)) == 0.0_dp) sys%fmode(j) = 0
        end do
        if (force_release > 0) then
            call dyn_hold(sys, t, y, hsave, stat)
            if (stat%code /= 0) return
            if (hsave(force_release) >= 0.0_dp) then
                sys%fmode(force_release) = -1
            else
                sys%fmode(force_release) = 1
            end if
        end if
        do pass = 1, 2*sys%npt + 1
            call dyn_hold(sys, t, y, hold, stat)
            if (stat%code /= 0) return
            jmax = 0
            emax = 0.0_dp
            do j = 1, 2*sys%npt
                if (sys%fric((j + 1)/2) == 0.0_dp .or. sys%fmode(j) /= 0) cycle
                excess = abs(hold(j)) - sys%fric((j + 1)/2)
                if (excess > emax) then
                    emax = excess
                    jmax = j
                end if
            end do
            if (jmax == 0) exit
            if (hold(jmax) > 0.0_dp) then
                sys%fmode(jmax) = -1
            else
                sys%fmode(jmax) = 1
            end if
        end do
    end subroutine dyn_switch

    !> Psidot = (1 + u') w'_t - w' u'_t at mass point k (Eq. 153).
    pure real(dp) function dyn_psidot(sys, q, v, k)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: q(:), v(:)
        integer, intent(in) :: k
        dyn_psidot = (1.0_dp + q(sys%idu(k)))*v(sys%idw(k)) - q(sys%idw(k))*v(sys%idu(k))
    end function dyn_psidot

    !> Friction shape phi(v) of the chosen law and its derivative.
    pure subroutine friction_phi(law, vslip, v, phi, dphi)
        integer, intent(in) :: law
        real(dp), intent(in) :: vslip, v
        real(dp), intent(out) :: phi, dphi
        real(dp) :: r
        dphi = 0.0_dp
        select case (law)
        case (FRICTION_SMOOTH)
            r = sqrt(v*v + vslip*vslip)
            phi = v/r
            dphi = vslip*vslip/r**3
        case (FRICTION_SIGN_LITERAL)
            phi = sign(1.0_dp, v)
        case default
            if (v > 0.0_dp) then
                phi = 1.0_dp
            else if (v < 0.0_dp) then
                phi = -1.0_dp
            else
                phi = 0.0_dp
            end if
        end select
    end subroutine friction_phi

    !> Motor torque: the state T with a lag, else -r g Psidot_tip (Eq. 150, 158).
    pure real(dp) function dyn_torque(sys, q, v, x)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: q(:), v(:), x(:)
        dyn_torque = 0.0_dp
        if (sys%motor /= 0.0_dp) dyn_torque = motor_torque(sys, q, v, x)
    end function dyn_torque

    pure real(dp) function motor_torque(sys, q, v, x)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: q(:), v(:), x(:)
        if (sys%nx > 0) then
            motor_torque = x(1)
        else
            motor_torque = -sys%motor*dyn_psidot(sys, q, v, sys%npt)
        end if
    end function motor_torque

    !> Curvature chi, its gradient dchi/dq and the shape-function derivatives
    !! at zeta in one element (Eq. 72).
    pure subroutine chi_gradient(h, qe, zeta, chi, dchi, g1, g2)
        real(dp), intent(in) :: h, qe(FE_NDOF), zeta
        real(dp), intent(out) :: chi, dchi(FE_NDOF), g1(4), g2(4)
        real(dp) :: f(4), a, b, c, d
        call fe_hermite(zeta, h, f, g1, g2)
        a = dot_product(g1, qe(FE_U))
        b = dot_product(g1, qe(FE_W))
        c = dot_product(g2, qe(FE_U))
        d = dot_product(g2, qe(FE_W))
        chi = d*(1.0_dp + a) - b*c
        dchi(FE_U) = d*g1 - b*g2
        dchi(FE_W) = (1.0_dp + a)*g2 - c*g1
    end subroutine chi_gradient

    !> Kelvin-Voigt damping of one element: force fd = int eta EI chidot dchi,
    !! power -int eta EI chidot^2, and optionally kd = dfd/dq, cd = dfd/dv.
    pure subroutine damping_element(h, c, xg, wg, qe, ve, fd, power, kd, cd)
        real(dp), intent(in) :: h, c      !< element length, eta EI
        real(dp), intent(in) :: xg(:), wg(:), qe(FE_NDOF), ve(FE_NDOF)
        real(dp), intent(out) :: fd(FE_NDOF), power
        real(dp), intent(out), optional :: kd(FE_NDOF, FE_NDOF), cd(FE_NDOF, FE_NDOF)
        real(dp) :: chi, dchi(FE_NDOF), g1(4), g2(4), rate, wt, hv(FE_NDOF), hm
        integer :: g, i, j
        fd = 0.0_dp
        power = 0.0_dp
        if (present(kd)) kd = 0.0_dp
        if (present(cd)) cd = 0.0_dp
        do g = 1, size(xg)
            call chi_gradient(h, qe, xg(g), chi, dchi, g1, g2)
            rate = dot_product(dchi, ve)
            wt = wg(g)*h*c
            fd = fd + wt*rate*dchi
            power = power - wt*rate*rate
            if (present(cd)) then
                do j = 1, FE_NDOF
                    cd(:, j) = cd(:, j) + wt*dchi*dchi(j)
                end do
            end if
            if (present(kd)) then
                ! H v with H = d2chi/dq2 (only the u-w blocks, Eq. 72)
                hv(FE_U) = g1*dot_product(g2, ve(FE_W)) - g2*dot_product(g1, ve(FE_W))
                hv(FE_W) = g2*dot_product(g1, ve(FE_U)) - g1*dot_product(g2, ve(FE_U))
                do j = 1, FE_NDOF
                    kd(:, j) = kd(:, j) + wt*dchi*hv(j)
                end do
                do j = 1, 4
                    do i = 1, 4
                        hm = wt*rate*(g1(i)*g2(j) - g2(i)*g1(j))
                        kd(FE_U(i), FE_W(j)) = kd(FE_U(i), FE_W(j)) + hm
                        kd(FE_W(j), FE_U(i)) = kd(FE_W(j), FE_U(i)) + hm
                    end do
                end do
            end if
        end do
    end subroutine damping_element

    !> Generalized force F(q, v, T) (everything but M q''), the work rates of
    !! the effects (`power`, nwork lines) and the motor torque.
    pure subroutine dyn_forces(sys, t, q, v, x, f, power, torque)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t           !< time (s): the forcings'
        real(dp), intent(in) :: q(:), v(:), x(:)
        real(dp), intent(out) :: f(:), power(:), torque
        call fe_internal_force(sys%mesh, q, f)
        f = -f
        call add_effects(sys, t, q, v, x, f, power, torque)
    end subroutine dyn_forces

    !> Work rates of the effects alone (no internal force): what the
    !! collocation quadrature of the ledger needs on converged stages.
    pure subroutine dyn_power(sys, t, q, v, x, power)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t           !< time (s): the forcings'
        real(dp), intent(in) :: q(:), v(:), x(:)
        real(dp), intent(out) :: power(:)
        real(dp) :: f(size(q)), torque
        f = 0.0_dp
        call add_effects(sys, t, q, v, x, f, power, torque)
    end subroutine dyn_power

    !> Add the nonconservative and velocity-dependent forces of the effects to
    !! f; their work rates and the motor torque (Eq. 101-102, 121-122, 130-132,
    !! 150-156).
    pure subroutine add_effects(sys, t, q, v, x, f, power, torque)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t           !< time (s): the forcings'
        real(dp), intent(in) :: q(:), v(:), x(:)
        real(dp), intent(inout) :: f(:)
        real(dp), intent(out) :: power(:), torque
        real(dp), allocatable :: qf(:), vf(:), ff(:)
        real(dp) :: phi, dphi, fd(FE_NDOF), pw, psid, jm
        integer :: k, i, c, el, npt, edx(FE_NDOF)
        npt = sys%npt
        power = 0.0_dp
        do k = 1, npt
            do c = 1, 2
                if (c == 1) then
                    i = sys%iu(k)
                else
                    i = sys%iw(k)
                end if
                if (sys%fric(k) /= 0.0_dp) then
                    if (sys%events) then
                        phi = real(sys%fmode(2*(k - 1) + c), dp)
                    else
                        call friction_phi(sys%law, sys%vslip, v(i), phi, dphi)
                    end if
                    f(i) = f(i) - sys%fric(k)*phi
                    power(k) = power(k) - sys%fric(k)*phi*v(i)
                end if
                if (sys%drag(k) /= 0.0_dp) then
                    f(i) = f(i) - sys%drag(k)*v(i)
                    power(npt + k) = power(npt + k) - sys%drag(k)*v(i)**2
                end if
            end do
            jm = sys%inertia(k)
            if (jm /= 0.0_dp) then
                psid = dyn_psidot(sys, q, v, k)
                f(sys%idw(k)) = f(sys%idw(k)) - 2.0_dp*jm*psid*v(sys%idu(k))
                f(sys%idu(k)) = f(sys%idu(k)) + 2.0_dp*jm*psid*v(sys%idw(k))
            end if
        end do
        if (sys%eta /= 0.0_dp) then
            allocate (qf(sys%mesh%ndof), vf(sys%mesh%ndof), ff(sys%mesh%ndof))
            call fe_expand(sys%mesh, q, qf)
            call fe_expand(sys%mesh, v, vf)
            ff = 0.0_dp
            do el = 1, sys%mesh%nel
                ! the element's unknowns (outboard slopes after a hinge)
                edx = sys%mesh%el_dof(:, el)
                call damping_element(sys%mesh%h(el), sys%eta*sys%mesh%ei(el), sys%mesh%xg, &
                                     sys%mesh%wg, qf(edx), vf(edx), fd, pw)
                ff(edx) = ff(edx) + fd
                power(2*npt + 1) = power(2*npt + 1) + pw
            end do
            f = f - ff(sys%mesh%full_of)
        end if
        torque = 0.0_dp
        if (sys%motor /= 0.0_dp) then
            torque = motor_torque(sys, q, v, x)
            f(sys%idw(npt)) = f(sys%idw(npt)) + torque*(1.0_dp + q(sys%idu(npt)))
            f(sys%idu(npt)) = f(sys%idu(npt)) - torque*q(sys%idw(npt))
            power(2*npt + 2) = torque*dyn_psidot(sys, q, v, npt)
        end if
        ! the forcings in time, each with its own work line
        if (sys%nloads > 0) call add_loads(sys, t, q, v, f, power(2*npt + 3:))
    end subroutine add_effects

    !> The forcings' forces and work rates (add_effects; kept apart so that the
    !! chain's own effects compile as before).
    pure subroutine add_loads(sys, t, q, v, f, power)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t, q(:), v(:)
        real(dp), intent(inout) :: f(:)
        real(dp), intent(inout) :: power(:)
        integer :: k
        do k = 1, sys%nloads
            call sys%loads(k)%f%apply(t, q, v, f, power(k))
        end do
    end subroutine add_loads

    !> Mass matrix M(q) in band storage (rotary inertia of Eq. 132 included).
    pure subroutine dyn_mass(sys, q, mb)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: mb(:, :)
        integer :: k, r0
        real(dp) :: a1, a2, jm
        mb = sys%mb
        if (.not. sys%rotary) return
        ! M(q) = M_c + sum_k J_k a_k a_k^T on (w', u') of each mass point (as
        ! fe_mass with rotary inertia): only four entries per mass change
        r0 = sys%mesh%kl + sys%mesh%ku + 1
        do k = 1, sys%npt
            jm = sys%inertia(k)
            if (jm == 0.0_dp) cycle
            a1 = 1.0_dp + q(sys%idu(k))
            a2 = -q(sys%idw(k))
            mb(r0, sys%idw(k)) = mb(r0, sys%idw(k)) + jm*a1*a1
            mb(r0, sys%idu(k)) = mb(r0, sys%idu(k)) + jm*a2*a2
            mb(r0 + sys%idw(k) - sys%idu(k), sys%idu(k)) = &
                mb(r0 + sys%idw(k) - sys%idu(k), sys%idu(k)) + jm*a1*a2
            mb(r0 + sys%idu(k) - sys%idw(k), sys%idw(k)) = &
                mb(r0 + sys%idu(k) - sys%idw(k), sys%idw(k)) + jm*a1*a2
        end do
    end subroutine dyn_mass

    !> Rates of the state y = (q, v, x): (v, M(q)^-1 F, x'), the work rates
    !! and the motor torque. x' = (-r g Psidot_tip - T)/tau with a motor lag.
    !! With friction events on, sticking components (fmode = 0) get zero
    !! acceleration by their constraint forces, returned in `hold`.
    subroutine dyn_rates(sys, t, y, dy, power, torque, stat, hold)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t           !< time (s): the forcings'
        real(dp), intent(in) :: y(:)
        real(dp), intent(out) :: dy(:), power(:), torque
        type(status_t), intent(inout) :: stat
        real(dp), intent(out), optional :: hold(:)
        type(band_lu_t) :: lu
        real(dp) :: hl(2*sys%npt)
        integer :: n, ios
        n = sys%n
        call dyn_forces(sys, t, y(1:n), y(n + 1:2*n), y(2*n + 1:), dy(n + 1:2*n), power, torque)
        dy(1:n) = y(n + 1:2*n)
        hl = 0.0_dp
        if (sys%rotary) then
            lu%n = n
            lu%kl = sys%mesh%kl
            lu%ku = sys%mesh%ku
            allocate (lu%ab(fe_band_rows(sys%mesh), n), stat=ios)
            if (ios /= 0) then
                call set_status(stat, ERR_INPUT, 'dyn_rates', 'cannot allocate the mass '// &
                                'matrix of '//fmt_int(n)//' unknowns')
                return
            end if
            call dyn_mass(sys, y(1:n), lu%ab)
            call band_factor(lu, stat)
            if (stat%code /= 0) return
            call band_solve(lu, dy(n + 1:2*n))
            if (sys%events) call constrain_rates(sys, lu, dy(n + 1:2*n), hl, stat)
        else
            call band_solve(sys%mlu, dy(n + 1:2*n))
            if (sys%events) call constrain_rates(sys, sys%mlu, dy(n + 1:2*n), hl, stat)
        end if
        if (present(hold)) hold = hl
        if (sys%nx > 0) then
            dy(2*n + 1) = (-sys%motor*dyn_psidot(sys, y(1:n), y(n + 1:2*n), sys%npt) &
                           - y(2*n + 1))/sys%tau
        end if
    end subroutine dyn_rates

    !> Jacobians of the generalized force: kb = -dF/dq and cb = -dF/dv (band
    !! storage), and for a motor lag the couplings b = dF/dT (dense n-vector),
    !! p = dT'/dq, d = dT'/dv, e = dT'/dT.
    pure subroutine dyn_jacobian(sys, t, q, v, x, kb, cb, b, p, d, e, force, power, torque)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t           !< time (s): the forcings'
        real(dp), intent(in) :: q(:), v(:), x(:)
        real(dp), intent(out) :: kb(:, :), b(:), p(:), d(:), e
        !> C = dF/dv; may be absent when dyn_velocity_coupled(sys) is false
        !! (C is zero by construction; nothing is written)
        real(dp), intent(out), optional :: cb(:, :)
        !> F, work rates and torque at the same state (as dyn_forces; the three
        !! together or none): the tangent assembly has the internal force anyway
        real(dp), intent(out), optional :: force(:), power(:)
        real(dp), intent(out), optional :: torque
        real(dp) :: f(sys%n), tq, g, a(2), dpsi_dq(2)
        integer :: k, aa, bb, kl, ku, idx(2)
        kl = sys%mesh%kl
        ku = sys%mesh%ku
        if (present(force)) then
            call fe_tangent(sys%mesh, q, f, kb)
            force = -f
            call add_effects(sys, t, q, v, x, force, power, torque)
        else
            call fe_tangent(sys%mesh, q, kb=kb)
        end if
        b = 0.0_dp
        p = 0.0_dp
        d = 0.0_dp
        e = 0.0_dp
        ! without cb (not dyn_velocity_coupled) the friction, drag, rotary
        ! inertia and damping terms are zero or absent: only the motor's
        if (present(cb)) call velocity_terms(sys, q, v, kb, cb)
        if (sys%motor /= 0.0_dp) then
            k = sys%npt
            idx = [sys%idw(k), sys%idu(k)]
            a = [1.0_dp + q(sys%idu(k)), -q(sys%idw(k))]
            dpsi_dq = [-v(sys%idu(k)), v(sys%idw(k))]   ! dPsidot/d(w', u')
            tq = motor_torque(sys, q, v, x)
            g = sys%motor
            ! F += T a: -d(T a)/dq through a, da/d(w', u') = [[0, 1], [-1, 0]]
            call fe_band_add(kb, kl, ku, idx(1), idx(2), -tq)
            call fe_band_add(kb, kl, ku, idx(2), idx(1), tq)
            if (sys%nx == 0) then
                ! T = -g Psidot: dT/dq = -g dpsi_dq, dT/dv = -g a
                do bb = 1, 2
                    do aa = 1, 2
                        call fe_band_add(kb, kl, ku, idx(aa), idx(bb), g*a(aa)*dpsi_dq(bb))
                        if (present(cb)) call fe_band_add(cb, kl, ku, idx(aa), idx(bb), &
                                                          g*a(aa)*a(bb))
                    end do
                end do
            else
                b(idx) = a
                p(idx) = -g*dpsi_dq/sys%tau
                d(idx) = -g*a/sys%tau
                e = -1.0_dp/sys%tau
            end if
        end if
        if (sys%nloads > 0) call loads_jacobian(sys, t, q, v, kb, cb)
    end subroutine dyn_jacobian

    !> The forcings' Jacobians (dyn_jacobian).
    pure subroutine loads_jacobian(sys, t, q, v, kb, cb)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t, q(:), v(:)
        real(dp), intent(inout) :: kb(:, :)
        real(dp), intent(inout), optional :: cb(:, :)
        integer :: k
        do k = 1, sys%nloads
            call sys%loads(k)%f%jacobian(t, q, v, sys%mesh%kl, sys%mesh%ku, kb, cb)
        end do
    end subroutine loads_jacobian

    !> The Jacobian terms of friction, drag, rotary inertia and Kelvin-Voigt
    !! damping (dyn_jacobian): C = dF/dv into cb (zeroed first), their
    !! dF/dq parts added to kb.
    pure subroutine velocity_terms(sys, q, v, kb, cb)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: q(:), v(:)
        real(dp), intent(inout) :: kb(:, :)
        real(dp), intent(out) :: cb(:, :)
        real(dp), allocatable :: qf(:), vf(:)
        real(dp) :: phi, dphi, jm, psid, wd, ud, wq, uq, fd(FE_NDOF), pw
        real(dp) :: kd(FE_NDOF, FE_NDOF), cd(FE_NDOF, FE_NDOF)
        integer :: k, c, i, el, aa, bb, ia, ib, kl, ku, edx(FE_NDOF)
        kl = sys%mesh%kl
        ku = sys%mesh%ku
        cb = 0.0_dp
        do k = 1, sys%npt
            do c = 1, 2
                if (c == 1) then
                    i = sys%iu(k)
                else
                    i = sys%iw(k)
                end if
                if (sys%fric(k) /= 0.0_dp) then
                    call friction_phi(sys%law, sys%vslip, v(i), phi, dphi)
                    call fe_band_add(cb, kl, ku, i, i, sys%fric(k)*dphi)
                end if
                if (sys%drag(k) /= 0.0_dp) call fe_band_add(cb, kl, ku, i, i, sys%drag(k))
            end do
            jm = sys%inertia(k)
            if (jm /= 0.0_dp) then
                ! g_rot = 2 J Psidot (u'_t, -w'_t) on (w', u'), added to -F
                psid = dyn_psidot(sys, q, v, k)
                wd = v(sys%idw(k))
                ud = v(sys%idu(k))
                wq = q(sys%idw(k))
                uq = q(sys%idu(k))
                call fe_band_add(cb, kl, ku, sys%idw(k), sys%idw(k), 2*jm*(1 + uq)*ud)
                call fe_band_add(cb, kl, ku, sys%idw(k), sys%idu(k), 2*jm*(psid - wq*ud))
                call fe_band_add(cb, kl, ku, sys%idu(k), sys%idw(k), -2*jm*((1 + uq)*wd + psid))
                call fe_band_add(cb, kl, ku, sys%idu(k), sys%idu(k), 2*jm*wq*wd)
                call fe_band_add(kb, kl, ku, sys%idw(k), sys%idw(k), -2*jm*ud*ud)
                call fe_band_add(kb, kl, ku, sys%idw(k), sys%idu(k), 2*jm*wd*ud)
                call fe_band_add(kb, kl, ku, sys%idu(k), sys%idw(k), 2*jm*ud*wd)
                call fe_band_add(kb, kl, ku, sys%idu(k), sys%idu(k), -2*jm*wd*wd)
            end if
        end do
        if (sys%eta /= 0.0_dp) then
            allocate (qf(sys%mesh%ndof), vf(sys%mesh%ndof))
            call fe_expand(sys%mesh, q, qf)
            call fe_expand(sys%mesh, v, vf)
            do el = 1, sys%mesh%nel
                edx = sys%mesh%el_dof(:, el)
                call damping_element(sys%mesh%h(el), sys%eta*sys%mesh%ei(el), sys%mesh%xg, &
                                     sys%mesh%wg, qf(edx), vf(edx), fd, pw, kd, cd)
                do bb = 1, FE_NDOF
                    ib = sys%mesh%free_of(edx(bb))
                    if (ib == 0) cycle
                    do aa = 1, FE_NDOF
                        ia = sys%mesh%free_of(edx(aa))
                        if (ia == 0) cycle
                        call fe_band_add(kb, kl, ku, ia, ib, kd(aa, bb))
                        call fe_band_add(cb, kl, ku, ia, ib, cd(aa, bb))
                    end do
                end do
            end do
        end if
    end subroutine velocity_terms

    !> Directional derivative (dC/dq)[vq] at rest (v = 0) of the damping
    !! matrix C = dF/dv of velocity_terms, in band storage (cb is zeroed):
    !! at rest only Kelvin-Voigt damping's sum wt dchi dchi^T depends on q
    !! (drag is constant; rotary inertia's and the friction's C vanish or are
    !! off), so dC = sum wt (Hc vq dchi^T + dchi (Hc vq)^T), Hc = d2chi/dq2.
    pure subroutine dyn_damping_dir(sys, q, vq, cb)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: q(:), vq(:)
        real(dp), intent(out) :: cb(:, :)
        real(dp), allocatable :: qf(:), vf(:)
        real(dp) :: chi, dchi(FE_NDOF), g1(4), g2(4), hv(FE_NDOF), wt, qe(FE_NDOF), &
                    ve(FE_NDOF), cd(FE_NDOF, FE_NDOF)
        integer :: el, g, aa, bb, ia, ib, edx(FE_NDOF)
        cb = 0.0_dp
        if (sys%eta == 0.0_dp) return
        allocate (qf(sys%mesh%ndof), vf(sys%mesh%ndof))
        call fe_expand(sys%mesh, q, qf)
        call fe_expand(sys%mesh, vq, vf)
        do el = 1, sys%mesh%nel
            edx = sys%mesh%el_dof(:, el)
            qe = qf(edx)
            ve = vf(edx)
            cd = 0.0_dp
            do g = 1, size(sys%mesh%xg)
                call chi_gradient(sys%mesh%h(el), qe, sys%mesh%xg(g), chi, dchi, g1, g2)
                wt = sys%mesh%wg(g)*sys%mesh%h(el)*sys%eta*sys%mesh%ei(el)
                hv(FE_U) = g1*dot_product(g2, ve(FE_W)) - g2*dot_product(g1, ve(FE_W))
                hv(FE_W) = g2*dot_product(g1, ve(FE_U)) - g1*dot_product(g2, ve(FE_U))
                do bb = 1, FE_NDOF
                    cd(:, bb) = cd(:, bb) + wt*(hv*dchi(bb) + dchi*hv(bb))
                end do
            end do
            do bb = 1, FE_NDOF
                ib = sys%mesh%free_of(edx(bb))
                if (ib == 0) cycle
                do aa = 1, FE_NDOF
                    ia = sys%mesh%free_of(edx(aa))
                    if (ia == 0) cycle
                    call fe_band_add(cb, sys%mesh%kl, sys%mesh%ku, ia, ib, cd(aa, bb))
                end do
            end do
        end do
    end subroutine dyn_damping_dir

    !> Whether the forces depend on the velocities through more than the
    !! sign law's constant friction (C = dF/dv nonzero somewhere): drag,
    !! Kelvin-Voigt damping, rotary inertia, the motor without lag or the
    !! regularized friction law. Otherwise C is zero by construction.
    pure logical function dyn_velocity_coupled(sys) result(coupled)
        type(dyn_system_t), intent(in) :: sys
        integer :: l
        coupled = sys%eta /= 0.0_dp .or. (sys%motor /= 0.0_dp .and. sys%nx == 0) .or. sys%rotary &
                  .or. any(sys%drag /= 0.0_dp) .or. any(sys%inertia /= 0.0_dp) &
                  .or. (sys%law == FRICTION_SMOOTH .and. any(sys%fric /= 0.0_dp))
        if (coupled) return
        do l = 1, sys%nloads
            coupled = coupled .or. sys%loads(l)%f%velocity_coupled()
        end do
    end function dyn_velocity_coupled

    !> Kinetic energy v^T M(q) v / 2 (Eq. 119, with Eq. 130) and strain energy (Eq. 87).
    pure subroutine dyn_energy(sys, q, v, kinetic, potential)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: q(:), v(:)
        real(dp), intent(out) :: kinetic, potential
        real(dp), allocatable :: mb(:, :), mv(:)
        allocate (mb(fe_band_rows(sys%mesh), sys%n), mv(sys%n))
        call dyn_mass(sys, q, mb)
        call fe_band_matvec(mb, sys%mesh%kl, sys%mesh%ku, v, mv)
        kinetic = 0.5_dp*dot_product(v, mv)
        potential = fe_energy(sys%mesh, q)
    end subroutine dyn_energy

    !> Tip u, w and angle atan2(w', 1 + u') from the free vector q.
    pure subroutine dyn_tip(sys, q, u, w, angle)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: u, w, angle
        integer :: k
        k = sys%npt
        u = q(sys%iu(k))
        w = q(sys%iw(k))
        angle = atan2(q(sys%idw(k)), 1.0_dp + q(sys%idu(k)))
    end subroutine dyn_tip

    ! ---------------------------------------------------------------------
    ! Integration coordinates: the free unknowns q (full model) or the modal
    ! coordinates eta of a truncated modal model q = Phi_r eta (Eq. 127,
    ! Section 4.1.4). Coordinate state yc = (c, c', x) with nc entries each
    ! for c and c'; matrices in band storage with half-bandwidths ckl, cku
    ! (dense k x k, stored with ckl = cku = k - 1, in the modal model).
    ! ---------------------------------------------------------------------

    !> Switch `sys` to the truncated modal model on the linear modes `modes`
    !! (indices into the ascending frequencies of fe_modes, Eq. 124-126): the
    !! modal equations Phi^T M Phi eta'' = Phi^T F(Phi eta, Phi eta') (Eq. 127)
    !! with the full nonlinear internal force and effects.
    subroutine dyn_set_modes(sys, modes, stat)
        type(dyn_system_t), intent(inout) :: sys
        integer, intent(in) :: modes(:)
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'dyn_set_modes'
        real(dp), allocatable :: omega(:), phi(:, :), q0(:), mb(:, :), md(:, :)
        logical, allocatable :: axial(:)
        integer :: n, k, i
        n = sys%n
        k = size(modes)
        if (k < 1 .or. k > n) then
            call set_status(stat, ERR_INPUT, where, 'number of modes = '//fmt_int(k)// &
                            ', expected 1..'//fmt_int(n))
            return
        end if
        do i = 1, k
            if (modes(i) < 1 .or. modes(i) > n) then
                call set_status(stat, ERR_INPUT, where, 'mode index '//fmt_int(modes(i))// &
                                ' out of range 1..'//fmt_int(n))
                return
            end if
            if (any(modes(1:i - 1) == modes(i))) then
                call set_status(stat, ERR_INPUT, where, 'mode index '//fmt_int(modes(i))// &
                                ' given twice')
                return
            end if
        end do
        allocate (omega(n), phi(n, n), axial(n), q0(n), mb(fe_band_rows(sys%mesh), n), md(n, k), &
                  stat=i)
        if (i /= 0) then
            call set_status(stat, ERR_INPUT, where, 'cannot allocate the '//fmt_int(n)//' x '// &
                            fmt_int(n)//' modes ('//fmt_real(8.0_dp*real(n, dp)**2)//' bytes)')
            return
        end if
        call fe_modes(sys%mesh, sys%rotary, omega, phi, axial, stat)
        if (stat%code /= 0) return
        sys%modal = .true.
        sys%phi = phi(:, modes)
        sys%omega_r = omega(modes)
        sys%nc = k
        sys%ckl = k - 1
        sys%cku = k - 1
        sys%ncstate = 2*k + sys%nx
        ! M~ = Phi^T M(0) Phi (= I for the mass-normalized modes, Eq. 125)
        q0 = 0.0_dp
        call fe_mass(sys%mesh, q0, sys%rotary, mb)
        do i = 1, k
            call fe_band_matvec(mb, sys%mesh%kl, sys%mesh%ku, sys%phi(:, i), md(:, i))
        end do
        sys%cmb = dense_to_band(matmul(transpose(sys%phi), md), k - 1)
        sys%cmlu%n = k
        sys%cmlu%kl = k - 1
        sys%cmlu%ku = k - 1
        sys%cmlu%ab = sys%cmb
        call band_factor(sys%cmlu, stat)
    end subroutine dyn_set_modes

    !> A dense k x k matrix in band storage with kl = ku = w (w >= k - 1).
    pure function dense_to_band(a, w) result(ab)
        real(dp), intent(in) :: a(:, :)
        integer, intent(in) :: w
        real(dp) :: ab(3*w + 1, size(a, 2))
        integer :: i, j
        ab = 0.0_dp
        do j = 1, size(a, 2)
            do i = 1, size(a, 1)
                ab(2*w + 1 + i - j, j) = a(i, j)
            end do
        end do
    end function dense_to_band

    !> Phi^T A Phi for a band matrix A (kl, ku of the mesh), in coordinate band
    !! storage (dense in the modal model).
    pure subroutine project_band(sys, ab, cb)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: ab(:, :)
        real(dp), intent(out) :: cb(:, :)
        real(dp) :: ap(sys%n, sys%nc)
        integer :: i
        do i = 1, sys%nc
            call fe_band_matvec(ab, sys%mesh%kl, sys%mesh%ku, sys%phi(:, i), ap(:, i))
        end do
        cb = dense_to_band(matmul(transpose(sys%phi), ap), sys%ckl)
    end subroutine project_band

    !> Physical state (q, v, x) of the coordinate state yc.
    pure subroutine dyn_to_physical(sys, yc, y)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: yc(:)
        real(dp), intent(out) :: y(:)
        integer :: n, k
        if (.not. sys%modal) then
            y = yc
            return
        end if
        n = sys%n
        k = sys%nc
        y(1:n) = matmul(sys%phi, yc(1:k))
        y(n + 1:2*n) = matmul(sys%phi, yc(k + 1:2*k))
        y(2*n + 1:) = yc(2*k + 1:)
    end subroutine dyn_to_physical

    !> Coordinate state of a physical state: eta = Phi^T M(0) q (the
    !! M-orthogonal projection on the retained modes; exact for q in their span).
    pure subroutine dyn_to_coords(sys, y, yc)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: y(:)
        real(dp), intent(out) :: yc(:)
        real(dp), allocatable :: mq(:), q0(:), mb(:, :)
        integer :: n, k
        if (.not. sys%modal) then
            yc = y
            return
        end if
        n = sys%n
        k = sys%nc
        allocate (mq(n), q0(n), mb(fe_band_rows(sys%mesh), n), source=0.0_dp)
        call fe_mass(sys%mesh, q0, sys%rotary, mb)
        call fe_band_matvec(mb, sys%mesh%kl, sys%mesh%ku, y(1:n), mq)
        yc(1:k) = matmul(mq, sys%phi)
        call fe_band_matvec(mb, sys%mesh%kl, sys%mesh%ku, y(n + 1:2*n), mq)
        yc(k + 1:2*k) = matmul(mq, sys%phi)
        yc(2*k + 1:) = y(2*n + 1:)
    end subroutine dyn_to_coords

    !> Generalized force in coordinates (F, or Phi^T F(Phi eta, Phi eta') in
    !! the modal model, Eq. 127), work rates and motor torque at the
    !! coordinate state yc.
    pure subroutine dyn_cforces(sys, t, yc, f, power, torque)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t           !< time (s): the forcings'
        real(dp), intent(in) :: yc(:)
        real(dp), intent(out) :: f(:), power(:), torque
        real(dp), allocatable :: y(:), fp(:)
        integer :: n, k
        k = sys%nc
        if (.not. sys%modal) then
            call dyn_forces(sys, t, yc(1:k), yc(k + 1:2*k), yc(2*k + 1:), f, power, torque)
            return
        end if
        n = sys%n
        allocate (y(sys%nstate), fp(n))
        call dyn_to_physical(sys, yc, y)
        call dyn_forces(sys, t, y(1:n), y(n + 1:2*n), y(2*n + 1:), fp, power, torque)
        f = matmul(fp, sys%phi)
    end subroutine dyn_cforces

    !> Work rates of the effects at the coordinate state yc.
    pure subroutine dyn_cpower(sys, t, yc, power)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t           !< time (s): the forcings'
        real(dp), intent(in) :: yc(:)
        real(dp), intent(out) :: power(:)
        real(dp), allocatable :: y(:)
        integer :: n, k
        k = sys%nc
        if (.not. sys%modal) then
            call dyn_power(sys, t, yc(1:k), yc(k + 1:2*k), yc(2*k + 1:), power)
            return
        end if
        n = sys%n
        allocate (y(sys%nstate))
        call dyn_to_physical(sys, yc, y)
        call dyn_power(sys, t, y(1:n), y(n + 1:2*n), y(2*n + 1:), power)
    end subroutine dyn_cpower

    !> Motor-lag rate x' = (-r g Psidot_tip - T) / tau at the coordinate state
    !! (Eq. 158 with the lag); 0 without a lag.
    pure real(dp) function dyn_cxrate(sys, yc) result(xd)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: yc(:)
        real(dp), allocatable :: y(:)
        integer :: n
        xd = 0.0_dp
        if (sys%nx == 0) return
        n = sys%n
        allocate (y(sys%nstate))
        call dyn_to_physical(sys, yc, y)
        xd = (-sys%motor*dyn_psidot(sys, y(1:n), y(n + 1:2*n), sys%npt) - y(2*n + 1))/sys%tau
    end function dyn_cxrate

    !> Mass matrix in coordinates (M(q), or Phi^T M(q) Phi), band storage
    !! with ckl, cku.
    pure subroutine dyn_cmass(sys, yc, mb)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: yc(:)
        real(dp), intent(out) :: mb(:, :)
        real(dp), allocatable :: q(:), mp(:, :)
        if (.not. sys%modal) then
            call dyn_mass(sys, yc(1:sys%n), mb)
        else if (.not. sys%rotary) then
            mb = sys%cmb
        else
            allocate (q(sys%n), mp(fe_band_rows(sys%mesh), sys%n))
            q = matmul(sys%phi, yc(1:sys%nc))
            call dyn_mass(sys, q, mp)
            call project_band(sys, mp, mb)
        end if
    end subroutine dyn_cmass

    !> Jacobians in coordinates: K~ = Phi^T K Phi, C~ = Phi^T C Phi and the
    !! motor-lag couplings Phi^T b, Phi^T p, Phi^T d (dyn_jacobian in the full
    !! model).
    pure subroutine dyn_cjacobian(sys, t, yc, kb, cb, b, p, d, e, force, power, torque)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t           !< time (s): the forcings'
        real(dp), intent(in) :: yc(:)
        real(dp), intent(out) :: kb(:, :), cb(:, :), b(:), p(:), d(:), e
        !> dyn_cforces at the same state, from the same assembly (optional)
        real(dp), intent(out), optional :: force(:), power(:)
        real(dp), intent(out), optional :: torque
        real(dp), allocatable :: y(:), kp(:, :), cp(:, :), bp(:), pp(:), dp_(:), fp(:)
        integer :: n, k, nb
        k = sys%nc
        if (.not. sys%modal) then
            call dyn_jacobian(sys, t, yc(1:k), yc(k + 1:2*k), yc(2*k + 1:), kb, cb, b, p, d, e, &
                              force, power, torque)
            return
        end if
        n = sys%n
        nb = fe_band_rows(sys%mesh)
        allocate (y(sys%nstate), kp(nb, n), cp(nb, n), bp(n), pp(n), dp_(n), fp(n))
        call dyn_to_physical(sys, yc, y)
        if (present(force)) then
            call dyn_jacobian(sys, t, y(1:n), y(n + 1:2*n), y(2*n + 1:), kp, cp, bp, pp, dp_, e, &
                              fp, power, torque)
            force = matmul(fp, sys%phi)
        else
            call dyn_jacobian(sys, t, y(1:n), y(n + 1:2*n), y(2*n + 1:), kp, cp, bp, pp, dp_, e)
        end if
        call project_band(sys, kp, kb)
        call project_band(sys, cp, cb)
        b = matmul(bp, sys%phi)
        p = matmul(pp, sys%phi)
        d = matmul(dp_, sys%phi)
    end subroutine dyn_cjacobian

    !> Rates of the coordinate state: (c', M~^-1 F~, x').
    subroutine dyn_crates(sys, t, yc, dy, power, torque, stat, hold)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t           !< time (s): the forcings'
        real(dp), intent(in) :: yc(:)
        real(dp), intent(out) :: dy(:), power(:), torque
        type(status_t), intent(inout) :: stat
        !> constraint forces of sticking friction components (full model)
        real(dp), intent(out), optional :: hold(:)
        type(band_lu_t) :: lu
        integer :: k
        if (.not. sys%modal) then
            call dyn_rates(sys, t, yc, dy, power, torque, stat, hold)
            return
        end if
        if (present(hold)) hold = 0.0_dp
        k = sys%nc
        call dyn_cforces(sys, t, yc, dy(k + 1:2*k), power, torque)
        dy(1:k) = yc(k + 1:2*k)
        if (sys%rotary) then
            lu%n = k
            lu%kl = sys%ckl
            lu%ku = sys%cku
            allocate (lu%ab(3*sys%ckl + 1, k))
            call dyn_cmass(sys, yc, lu%ab)
            call band_factor(lu, stat)
            if (stat%code /= 0) return
            call band_solve(lu, dy(k + 1:2*k))
        else
            call band_solve(sys%cmlu, dy(k + 1:2*k))
        end if
        if (sys%nx > 0) dy(2*k + 1) = dyn_cxrate(sys, yc)
    end subroutine dyn_crates

    ! ---------------------------------------------------------------------
    ! Parameter derivatives for the forward sensitivities (Eq. 135-140):
    ! the partial derivatives at a fixed state of the generalized force F,
    ! the motor-lag rate x', the mass matrix M and the strain energy, with
    ! respect to one model parameter or one component of the release load.
    ! Every term of F, M and V is linear in the parameter group it carries
    ! (EI, EA, C, rho, m, J, mu m, c, eta EI, r g, 1/flex, 1/tau), so each
    ! derivative is that term evaluated with the parameter set to one (or,
    ! for the compliances and the lag, the term times -1/p): exact, hand-coded.
    ! ---------------------------------------------------------------------

    !> Set up the derivative with respect to parameter `index` of the chain's
    !! flat parameter vector (beamid_model layout), or, when `iload` (= index
    !! - param_count) is 1..3, to the release load's fx, fy, moment. A
    !! parameter the dynamics do not depend on (axial_coupling, a motor
    !! parameter without motor) gets DP_NONE: a zero column.
    subroutine dyn_param_setup(sys, chain, iload, index, par, stat)
        type(dyn_system_t), intent(in) :: sys
        type(chain_t), intent(in) :: chain
        integer, intent(in) :: iload, index
        type(dyn_param_t), intent(out) :: par
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'dyn_param_setup'
        integer :: nb, i, k, which, el, a, b, ia, ib, node
        real(dp) :: me(FE_NDOF, FE_NDOF)
        nb = chain%nbeams
        par%kind = DP_NONE
        if (iload >= 1) then
            par%kind = DP_LOAD
            par%k = iload
            return
        end if
        i = index
        if (i <= PER_BEAM*nb) then
            k = (i - 1)/PER_BEAM + 1
            which = i - PER_BEAM*(k - 1)
            par%k = k
            select case (which)
            case (IB_EI)
                par%kind = DP_EI
            case (IB_EA)
                par%kind = DP_EA
            case (IB_C)
                par%kind = DP_CUBIC
            case (IB_RHO)
                par%kind = DP_RHO
                allocate (par%dmb(fe_band_rows(sys%mesh), sys%n))
                par%dmb = 0.0_dp
                do el = 1, sys%mesh%nel
                    if (sys%mesh%beam(el) /= k) cycle
                    call fe_element_mass(sys%mesh%h(el), 1.0_dp, me)
                    do b = 1, FE_NDOF
                        ib = sys%mesh%el_free(b, el)
                        if (ib == 0) cycle
                        do a = 1, FE_NDOF
                            ia = sys%mesh%el_free(a, el)
                            if (ia == 0) cycle
                            call fe_band_add(par%dmb, sys%mesh%kl, sys%mesh%ku, ia, ib, me(a, b))
                        end do
                    end do
                end do
            case default
                call set_status(stat, ERR_INPUT, where, 'sensitivity with respect to '// &
                                param_name(nb, index)//' (the mesh depends on it) is not '// &
                                'available')
            end select
        else if (i <= (PER_BEAM + PER_MASS)*nb) then
            i = i - PER_BEAM*nb
            k = (i - 1)/PER_MASS + 1
            which = i - PER_MASS*(k - 1)
            par%k = k
            select case (which)
            case (IM_M)
                par%kind = DP_MASS
                allocate (par%dmb(fe_band_rows(sys%mesh), sys%n))
                par%dmb = 0.0_dp
                call fe_band_add(par%dmb, sys%mesh%kl, sys%mesh%ku, sys%iw(k), sys%iw(k), 1.0_dp)
                call fe_band_add(par%dmb, sys%mesh%kl, sys%mesh%ku, sys%iu(k), sys%iu(k), 1.0_dp)
                par%dcap = chain%friction(k)*GRAVITY
            case (IM_J)
                par%kind = DP_J
            case (IM_MU)
                par%kind = DP_MU
                par%dcap = chain%mass(k)*GRAVITY
            case (IM_C)
                par%kind = DP_DRAG
            end select
        else if (i <= (PER_BEAM + PER_MASS)*nb + nb - 1) then
            k = i - (PER_BEAM + PER_MASS)*nb
            par%kind = DP_FLEX
            par%k = k
            node = k*(sys%mesh%nel/nb) + 1
            par%spring = -1
            do a = 1, sys%mesh%nhinge
                if (sys%mesh%hinge_node(a) == node) par%spring = a
            end do
            if (par%spring < 0) then
                call set_status(stat, ERR_INPUT, where, 'sensitivity with respect to '// &
                                param_name(nb, index)//' at 0 (a locked joint) is not '// &
                                'available: give it a positive compliance')
            end if
        else
            k = i - (PER_BEAM + PER_MASS)*nb - (nb - 1)
            select case (k)
            case (IG_ROOT_FLEX)
                par%kind = DP_FLEX
                par%spring = 0
                if (.not. (sys%mesh%root_flex > 0.0_dp)) then
                    call set_status(stat, ERR_INPUT, where, 'sensitivity with respect to '// &
                                    'root_flex at 0 (a clamped root) is not available: '// &
                                    'give it a positive compliance')
                end if
            case (IG_ETA)
                par%kind = DP_ETA
            case (IG_R_MOTOR)
                if (sys%gain /= 0.0_dp) par%kind = DP_R
            case (IG_TAU_MOTOR)
                if (sys%nx > 0) par%kind = DP_TAU
            end select
        end if
    end subroutine dyn_param_setup

    !> Element unknowns of element el from the free vector q.
    pure function elem_q(mesh, q, el) result(qe)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        integer, intent(in) :: el
        real(dp) :: qe(FE_NDOF)
        integer :: a
        do a = 1, FE_NDOF
            if (mesh%el_free(a, el) == 0) then
                qe(a) = 0.0_dp
            else
                qe(a) = q(mesh%el_free(a, el))
            end if
        end do
    end function elem_q

    !> dNLT/dp at q (internal force, Eq. 79-83, with the hinge springs): the
    !! stiffness parameters only (zero for the others).
    pure subroutine dyn_dnlt(sys, par, q, g)
        type(dyn_system_t), intent(in) :: sys
        type(dyn_param_t), intent(in) :: par
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: g(:)
        real(dp) :: fe(FE_NDOF), ea, ei, cu, flex, fs(4)
        integer :: el, a, idx(4)
        g = 0.0_dp
        select case (par%kind)
        case (DP_EI, DP_EA, DP_CUBIC)
            ea = merge(1.0_dp, 0.0_dp, par%kind == DP_EA)
            ei = merge(1.0_dp, 0.0_dp, par%kind == DP_EI)
            cu = merge(1.0_dp, 0.0_dp, par%kind == DP_CUBIC)
            do el = 1, sys%mesh%nel
                if (sys%mesh%beam(el) /= par%k) cycle
                call fe_element_force_tabulated(size(sys%mesh%xg), &
                                                sys%mesh%gauss_d1(:, :, par%k), &
                                                sys%mesh%gauss_d2(:, :, par%k), &
                                                sys%mesh%gauss_wh(:, par%k), ea, ei, cu, &
                                                elem_q(sys%mesh, q, el), fe)
                do a = 1, FE_NDOF
                    if (sys%mesh%el_free(a, el) /= 0) &
                        g(sys%mesh%el_free(a, el)) = g(sys%mesh%el_free(a, el)) + fe(a)
                end do
            end do
        case (DP_FLEX)
            ! the spring force (dpsi / f) grad(dpsi): d/df = -force / f
            call fe_spring_dofs(sys%mesh, par%spring, idx, flex)
            call fe_hinge_force(flex, spring_vals(q, idx), fs)
            do a = 1, 4
                if (idx(a) /= 0) g(idx(a)) = g(idx(a)) - fs(a)/flex
            end do
        end select
    end subroutine dyn_dnlt

    pure function spring_vals(q, idx) result(s)
        real(dp), intent(in) :: q(:)
        integer, intent(in) :: idx(4)
        real(dp) :: s(4)
        integer :: a
        do a = 1, 4
            s(a) = 0.0_dp
            if (idx(a) /= 0) s(a) = q(idx(a))
        end do
    end function spring_vals

    !> dV/dp at q (strain energy, Eq. 87, with the springs).
    pure real(dp) function dyn_denergy(sys, par, q) result(dv)
        type(dyn_system_t), intent(in) :: sys
        type(dyn_param_t), intent(in) :: par
        real(dp), intent(in) :: q(:)
        real(dp) :: ea, ei, cu, flex
        integer :: el, idx(4)
        dv = 0.0_dp
        select case (par%kind)
        case (DP_EI, DP_EA, DP_CUBIC)
            ea = merge(1.0_dp, 0.0_dp, par%kind == DP_EA)
            ei = merge(1.0_dp, 0.0_dp, par%kind == DP_EI)
            cu = merge(1.0_dp, 0.0_dp, par%kind == DP_CUBIC)
            do el = 1, sys%mesh%nel
                if (sys%mesh%beam(el) /= par%k) cycle
                dv = dv + fe_element_energy(sys%mesh%h(el), ea, ei, cu, sys%mesh%xg, &
                                            sys%mesh%wg, elem_q(sys%mesh, q, el))
            end do
        case (DP_FLEX)
            call fe_spring_dofs(sys%mesh, par%spring, idx, flex)
            dv = -fe_hinge_energy(flex, spring_vals(q, idx))/flex
        end select
    end function dyn_denergy

    !> Partial derivatives at the state (q, v, x) of the generalized force,
    !! fp = dF/dp, and of the motor-lag rate, xp = dx'/dp (Eq. 138, 140 and
    !! their counterparts for every effect). The mass matrix term is separate
    !! (dyn_dmass_mv).
    pure subroutine dyn_dforce(sys, t, par, q, v, x, fp, xp)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t           !< time (s): the forcings'
        type(dyn_param_t), intent(in) :: par
        real(dp), intent(in) :: q(:), v(:), x(:)
        real(dp), intent(out) :: fp(:), xp
        real(dp) :: phi, dphi, psid, fd(FE_NDOF), pw, c, xd
        integer :: k, cc, i, el, a, npt
        fp = 0.0_dp
        xp = 0.0_dp
        npt = sys%npt
        k = par%k
        select case (par%kind)
        case (DP_EI, DP_EA, DP_CUBIC, DP_FLEX)
            call dyn_dnlt(sys, par, q, fp)
            fp = -fp
            if (par%kind == DP_EI .and. sys%eta /= 0.0_dp) then
                do el = 1, sys%mesh%nel
                    if (sys%mesh%beam(el) /= k) cycle
                    call damping_element(sys%mesh%h(el), sys%eta, sys%mesh%xg, sys%mesh%wg, &
                                         elem_q(sys%mesh, q, el), elem_q(sys%mesh, v, el), &
                                         fd, pw)
                    do a = 1, FE_NDOF
                        i = sys%mesh%el_free(a, el)
                        if (i /= 0) fp(i) = fp(i) - fd(a)
                    end do
                end do
            end if
        case (DP_ETA)
            do el = 1, sys%mesh%nel
                call damping_element(sys%mesh%h(el), sys%mesh%ei(el), sys%mesh%xg, &
                                     sys%mesh%wg, elem_q(sys%mesh, q, el), &
                                     elem_q(sys%mesh, v, el), fd, pw)
                do a = 1, FE_NDOF
                    i = sys%mesh%el_free(a, el)
                    if (i /= 0) fp(i) = fp(i) - fd(a)
                end do
            end do
        case (DP_MU, DP_MASS)
            ! friction -mu m g phi: d/dmu = -m g phi, d/dm = -mu g phi
            if (par%dcap /= 0.0_dp) then
                do cc = 1, 2
                    i = merge(sys%iu(k), sys%iw(k), cc == 1)
                    if (sys%events) then
                        phi = real(sys%fmode(2*(k - 1) + cc), dp)
                    else
                        call friction_phi(sys%law, sys%vslip, v(i), phi, dphi)
                    end if
                    fp(i) = fp(i) - par%dcap*phi
                end do
            end if
        case (DP_DRAG)
            fp(sys%iu(k)) = -v(sys%iu(k))
            fp(sys%iw(k)) = -v(sys%iw(k))
        case (DP_J)
            psid = dyn_psidot(sys, q, v, k)
            fp(sys%idw(k)) = -2.0_dp*psid*v(sys%idu(k))
            fp(sys%idu(k)) = 2.0_dp*psid*v(sys%idw(k))
        case (DP_R)
            ! T = -r g Psidot (no lag): dT/dr = -g Psidot acting through a_tip;
            ! with the lag x' = (-r g Psidot - T)/tau: dx'/dr = -g Psidot/tau
            psid = dyn_psidot(sys, q, v, npt)
            if (sys%nx == 0) then
                c = -sys%gain*psid
                fp(sys%idw(npt)) = c*(1.0_dp + q(sys%idu(npt)))
                fp(sys%idu(npt)) = -c*q(sys%idw(npt))
            else
                xp = -sys%gain*psid/sys%tau
            end if
        case (DP_TAU)
            xd = (-sys%motor*dyn_psidot(sys, q, v, npt) - x(1))/sys%tau
            xp = -xd/sys%tau
        case (DP_FORCING)
            call sys%loads(k)%f%dforce(par%ip, t, q, v, fp)
        end select
        ! forcings proportional to the masses (the hub frame's inertial forces)
        if (par%kind == DP_RHO .or. par%kind == DP_MASS) then
            do i = 1, sys%nloads
                if (par%kind == DP_RHO) then
                    call sys%loads(i)%f%dmass(k, 0, t, q, v, fp)
                else
                    call sys%loads(i)%f%dmass(0, sys%iu(k), t, q, v, fp)
                end if
            end do
        end if
    end subroutine dyn_dforce

    !> y += (dM/dp) a at q (density, point mass, rotary inertia).
    pure subroutine dyn_dmass_mv(sys, par, q, a, y)
        type(dyn_system_t), intent(in) :: sys
        type(dyn_param_t), intent(in) :: par
        real(dp), intent(in) :: q(:), a(:)
        real(dp), intent(inout) :: y(:)
        real(dp) :: a1, a2, s
        integer :: k
        select case (par%kind)
        case (DP_RHO, DP_MASS)
            ! the product's work vector only here (the other kinds take none)
            block
                real(dp) :: t(size(a))
                call fe_band_matvec(par%dmb, sys%mesh%kl, sys%mesh%ku, a, t)
                y = y + t
            end block
        case (DP_J)
            k = par%k
            a1 = 1.0_dp + q(sys%idu(k))
            a2 = -q(sys%idw(k))
            s = a1*a(sys%idw(k)) + a2*a(sys%idu(k))
            y(sys%idw(k)) = y(sys%idw(k)) + s*a1
            y(sys%idu(k)) = y(sys%idu(k)) + s*a2
        end select
    end subroutine dyn_dmass_mv

    !> y += (dM/dq s) a: the rotary inertia part R(q) = sum J a_k a_k^T
    !! (Eq. 130-132), a_k = (1 + u', -w') on (w', u'), da_k = (s_u', -s_w').
    pure subroutine dyn_dmass_dq_mv(sys, q, s, a, y)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: q(:), s(:), a(:)
        real(dp), intent(inout) :: y(:)
        real(dp) :: a1, a2, d1, d2, aa, da
        integer :: k
        if (.not. sys%rotary) return
        do k = 1, sys%npt
            if (sys%inertia(k) == 0.0_dp) cycle
            a1 = 1.0_dp + q(sys%idu(k))
            a2 = -q(sys%idw(k))
            d1 = s(sys%idu(k))
            d2 = -s(sys%idw(k))
            aa = a1*a(sys%idw(k)) + a2*a(sys%idu(k))
            da = d1*a(sys%idw(k)) + d2*a(sys%idu(k))
            y(sys%idw(k)) = y(sys%idw(k)) + sys%inertia(k)*(d1*aa + a1*da)
            y(sys%idu(k)) = y(sys%idu(k)) + sys%inertia(k)*(d2*aa + a2*da)
        end do
    end subroutine dyn_dmass_dq_mv

    !> Sensitivity of the static equilibrium q0 under `load` (implicit function
    !! theorem on b(q, p) = NLT - Q = 0, Eq. 84-85): K_T dq0/dp = -db/dp with
    !! the Newton tangent K_T = db/dq, all parameters at once (one band LU,
    !! several right-hand sides). s(:, j): dq0/dp_j.
    subroutine dyn_static_sens(sys, load, q, pars, s, stat)
        type(dyn_system_t), intent(in) :: sys
        type(fe_load_t), intent(in) :: load
        real(dp), intent(in) :: q(:)
        type(dyn_param_t), intent(in) :: pars(:)
        real(dp), intent(out) :: s(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: jb(:, :), r(:), g(:), rhs(:, :)
        type(fe_load_t) :: unit
        integer :: j
        if (size(pars) == 0) return
        allocate (jb(fe_band_rows(sys%mesh), sys%n), r(sys%n), g(sys%n))
        call fe_residual(sys%mesh, load, q, r, jb)
        do j = 1, size(pars)
            if (pars(j)%kind == DP_LOAD) then
                ! Q is linear in each load component: dQ/dp = Q of the unit load
                unit = fe_load_t()
                unit%moment_form = load%moment_form
                if (pars(j)%k == 1) unit%fx = 1.0_dp
                if (pars(j)%k == 2) unit%fy = 1.0_dp
                if (pars(j)%k == 3) unit%moment = 1.0_dp
                call fe_tip_load(sys%mesh, q, unit, g)
                s(:, j) = g
            else
                call dyn_dnlt(sys, pars(j), q, g)
                s(:, j) = -g
            end if
        end do
        ! (s may be a section of the state's sensitivities, its first n rows:
        ! LAPACK takes a contiguous copy, made here once)
        rhs = s
        call solve_banded(sys%mesh%kl, sys%mesh%ku, jb, rhs, stat)
        s = rhs
    end subroutine dyn_static_sens

    !> Sensitivities of the outputs at the state y from the state sensitivity
    !! s: tip (u, w), tip angle, motor torque and total energy T + V.
    pure subroutine dyn_output_sens(sys, par, y, s, duw, dangle, dtorque, denergy)
        type(dyn_system_t), intent(in) :: sys
        type(dyn_param_t), intent(in) :: par
        real(dp), intent(in) :: y(:), s(:)
        real(dp), intent(out) :: duw(2), dangle, dtorque, denergy
        real(dp), allocatable :: mb(:, :), t(:), f(:)
        real(dp) :: a1, a2, dpsi
        integer :: n, k
        n = sys%n
        k = sys%npt
        duw = [s(sys%iu(k)), s(sys%iw(k))]
        a1 = 1.0_dp + y(sys%idu(k))
        a2 = y(sys%idw(k))
        dangle = (a1*s(sys%idw(k)) - a2*s(sys%idu(k)))/(a1*a1 + a2*a2)
        dtorque = 0.0_dp
        if (sys%motor /= 0.0_dp) then
            if (sys%nx > 0) then
                dtorque = s(2*n + 1)
            else
                dpsi = s(sys%idu(k))*y(n + sys%idw(k)) + a1*s(n + sys%idw(k)) &
                       - s(sys%idw(k))*y(n + sys%idu(k)) - a2*s(n + sys%idu(k))
                dtorque = -sys%motor*dpsi
                if (par%kind == DP_R) dtorque = dtorque - sys%gain*dyn_psidot(sys, y(1:n), &
                                                                              y(n + 1:2*n), k)
            end if
        end if
        ! E = v^T M(q) v / 2 + V(q)
        allocate (mb(fe_band_rows(sys%mesh), n), t(n), f(n))
        call dyn_mass(sys, y(1:n), mb)
        call fe_band_matvec(mb, sys%mesh%kl, sys%mesh%ku, y(n + 1:2*n), t)
        denergy = dot_product(t, s(n + 1:2*n))
        t = 0.0_dp
        call dyn_dmass_dq_mv(sys, y(1:n), s(1:n), y(n + 1:2*n), t)
        call dyn_dmass_mv(sys, par, y(1:n), y(n + 1:2*n), t)
        denergy = denergy + 0.5_dp*dot_product(t, y(n + 1:2*n))
        call fe_internal_force(sys%mesh, y(1:n), f)
        denergy = denergy + dot_product(f, s(1:n)) + dyn_denergy(sys, par, y(1:n))
    end subroutine dyn_output_sens

    !> Constrain a rate-form acceleration (change) to the sticking friction
    !! components (constrain_rates; linear in a): the constraint forces in hold.
    subroutine dyn_constrain(sys, lu, a, hold, stat)
        type(dyn_system_t), intent(in) :: sys
        type(band_lu_t), intent(in) :: lu
        real(dp), intent(inout) :: a(:)
        real(dp), intent(out) :: hold(:)
        type(status_t), intent(inout) :: stat
        call constrain_rates(sys, lu, a, hold, stat)
    end subroutine dyn_constrain

    !> d(mu m g)/dp of the friction cap at mass point `point` (UNSTICK events).
    pure real(dp) function dyn_param_dcap(par, point) result(dcap)
        type(dyn_param_t), intent(in) :: par
        integer, intent(in) :: point
        dcap = 0.0_dp
        if ((par%kind == DP_MU .or. par%kind == DP_MASS) .and. par%k == point) dcap = par%dcap
    end function dyn_param_dcap

    ! ------------------------------------------------------------ time

    !> The one evaluation entry of the integrators: everything they need of
    !! the model at time t and coordinate state yc (time enters the model only
    !! here, through the forcings). What is computed follows the outputs
    !! given, in this order of precedence:
    !! - `par` with `fp`, `xp`: dF/dp and dx'/dp of one parameter (full model);
    !! - `kb` (with `b`, `p`, `d`, `e`; `cb` unless not dyn_velocity_coupled in
    !!   the full model): the Jacobians, and with `force` also F, `power`,
    !!   `torque` from the same assembly (dyn_cjacobian);
    !! - `rates`: (c', M~^-1 F~, x'), `power`, `torque`, `hold` (dyn_crates);
    !! - `force`: F~, `power`, `torque` (dyn_cforces);
    !! - `power` alone: the work rates (dyn_cpower).
    !! `xrate` (with `kb` or `force`): the motor-lag rate x'.
    subroutine dyn_eval(sys, t, yc, stat, rates, hold, force, power, torque, xrate, &
                        kb, cb, b, p, d, e, par, fp, xp)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t          !< time (s)
        real(dp), intent(in) :: yc(:)      !< coordinate state (c, c', x)
        type(status_t), intent(inout) :: stat
        real(dp), intent(out), optional :: rates(:), hold(:), force(:), power(:), torque
        real(dp), intent(out), optional :: xrate
        real(dp), intent(out), optional :: kb(:, :), cb(:, :), b(:), p(:), d(:), e
        type(dyn_param_t), intent(in), optional :: par
        real(dp), intent(out), optional :: fp(:), xp
        real(dp) :: tq, pw(sys%nwork)
        integer :: k
        k = sys%nc
        if (present(par)) then
            call dyn_dforce(sys, t, par, yc(1:k), yc(k + 1:2*k), yc(2*k + 1:), fp, xp)
        else if (present(kb)) then
            if (sys%modal) then
                call dyn_cjacobian(sys, t, yc, kb, cb, b, p, d, e, force, power, torque)
            else
                call dyn_jacobian(sys, t, yc(1:k), yc(k + 1:2*k), yc(2*k + 1:), kb, cb, b, p, &
                                  d, e, force, power, torque)
            end if
            if (present(xrate)) xrate = dyn_cxrate(sys, yc)
        else if (present(rates)) then
            if (present(power)) then
                call dyn_crates(sys, t, yc, rates, power, tq, stat, hold)
            else
                call dyn_crates(sys, t, yc, rates, pw, tq, stat, hold)
            end if
            if (present(torque)) torque = tq
        else if (present(force)) then
            if (present(power)) then
                call dyn_cforces(sys, t, yc, force, power, tq)
            else
                call dyn_cforces(sys, t, yc, force, pw, tq)
            end if
            if (present(torque)) torque = tq
            if (present(xrate)) xrate = dyn_cxrate(sys, yc)
        else if (present(power)) then
            call dyn_cpower(sys, t, yc, power)
        end if
    end subroutine dyn_eval

    !> Append a forcing to the system: its force enters every evaluation, its
    !! work a new ledger line (the last).
    subroutine dyn_add_forcing(sys, f)
        type(dyn_system_t), intent(inout) :: sys
        class(forcing_t), intent(in) :: f
        type(forcing_slot_t), allocatable :: grown(:)
        integer :: l
        allocate (grown(sys%nloads + 1))
        do l = 1, sys%nloads
            call move_alloc(sys%loads(l)%f, grown(l)%f)
        end do
        allocate (grown(sys%nloads + 1)%f, source=f)
        call move_alloc(grown, sys%loads)
        sys%nloads = sys%nloads + 1
        sys%nwork = sys%nwork + 1
    end subroutine dyn_add_forcing

    !> Name of work line i of the ledger: friction_<point>, drag_<point> per
    !! mass point, damping, motor (the chain's lines, nbeams beams), then the
    !! forcings' own names (with `sys`).
    pure function dyn_work_name(nbeams, i, sys) result(name)
        integer, intent(in) :: nbeams, i
        type(dyn_system_t), intent(in), optional :: sys
        character(len=:), allocatable :: name
        integer :: k
        if (i > 2*nbeams + 2) then
            name = 'load'//fmt_int(i - 2*nbeams - 2)
            if (present(sys)) then
                if (i - 2*nbeams - 2 <= sys%nloads) name = sys%loads(i - 2*nbeams - 2)%f%work_name()
            end if
            return
        end if
        if (i > 2*nbeams) then
            name = merge('damping', 'motor  ', i == 2*nbeams + 1)
            name = trim(name)
            return
        end if
        k = mod(i - 1, nbeams) + 1
        name = merge('friction_', 'drag_    ', i <= nbeams)
        name = trim(name)
        if (k == nbeams) then
            name = name//'tip'
        else if (k == 1) then
            name = name//'elbow'
        else
            name = name//'joint'//fmt_int(k)
        end if
    end function dyn_work_name

    !> d tb/dp of breakpoint tb for parameter par (a forcing's parameter that
    !! moves a jump of its force; 0 otherwise).
    pure real(dp) function dyn_dbreak(sys, par, tb) result(d)
        type(dyn_system_t), intent(in) :: sys
        type(dyn_param_t), intent(in) :: par
        real(dp), intent(in) :: tb
        d = 0.0_dp
        if (par%kind == DP_FORCING) d = sys%loads(par%k)%f%dbreak(par%ip, tb)
    end function dyn_dbreak

    !> The forcings' breakpoints in (t0, t1], ascending, without repeats:
    !! the times an integrator steps onto.
    pure function dyn_breakpoints(sys, t0, t1) result(tb)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t0, t1
        real(dp), allocatable :: tb(:)
        real(dp), allocatable :: tt(:), one(:)
        real(dp) :: x
        integer :: l, i, j, n
        allocate (tt(0))
        do l = 1, sys%nloads
            one = sys%loads(l)%f%breakpoints(t0, t1)
            tt = [tt, pack(one, one > t0 .and. one <= t1)]
        end do
        ! insertion sort (few entries), then drop repeats
        do i = 2, size(tt)
            x = tt(i)
            j = i - 1
            do while (j >= 1)
                if (tt(j) <= x) exit
                tt(j + 1) = tt(j)
                j = j - 1
            end do
            tt(j + 1) = x
        end do
        allocate (tb(size(tt)))
        n = 0
        do i = 1, size(tt)
            if (n > 0) then
                if (tt(i) == tb(n)) cycle
            end if
            n = n + 1
            tb(n) = tt(i)
        end do
        tb = tb(1:n)
    end function dyn_breakpoints

end module beamid_dynamics
