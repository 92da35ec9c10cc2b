!> Modal analysis of the finite element chain about a static equilibrium
!! (issue 27): the arm held by a tip load (none, a tip force, a tip moment),
!! linearized about its equilibrium q*(p),
!!
!!     M(q*) x'' + C(q*) x' + K_T(q*) x = 0,
!!
!! K_T = d(NLT - Q)/dq (the Newton matrix of Eq. 85, with the hinge springs of
!! the root and joint compliances and the cubic law), M the consistent mass
!! with the point masses and, for J > 0, their rotary inertia (Eq. 130-132,
!! evaluated at q*), C = -dF/dv of the dynamics at rest: viscous drag at the
!! mass points and Kelvin-Voigt damping eta EI dchi/dt (beamid_dynamics). The
!! velocity terms of rotary inertia are quadratic in v and vanish at rest.
!! Coulomb friction has no linearization about rest (sign(v) jumps there):
!! the modal model leaves it out, so mu_* have a zero column. The FE model is
!! the exact elastica: axial_coupling (the arc-length model's switch) has no
!! effect either, nor have the motor parameters (no motor in a modal test).
!! The tip moment of Eq. 78 is not conservative (its tangent is
!! unsymmetric): it is refused; a tip moment takes the exact form
!! (FE_MOMENT_EXACT).
!!
!! About a radial wire (wire_length > 0, Eq. 22, fe_solve_wire): the wire
!! stays on during the test, inextensible and taut, so the tip moves on the
!! circle |x| = Lw: the modes are those of the constrained problem. With T
!! the tension at q*, e = x/|x| the wire's direction at the tip and
!! H = (I - e e^T)/|x| on the tip's (u, w), the stiffness is K_T + T H
!! (the wire's geometric stiffness: the Hessian of U + T g, g = |x| - Lw)
!! and the motion keeps e^T dx = 0. One tip unknown is eliminated, q = Z y
!! (the one of the larger |e| component, j: q_j = -(e_k/e_j) q_k), and the
!! modes of (Z^T K Z, Z^T M Z, Z^T C Z) are sought; phi = Z y. The model has
!! n - 1 modes. Sensitivities: (dq*, dT) from the bordered tangent
!! [K_T + T H, e; e^T, 0] (dq*, dT) = (-dR/dp, 0); dK gains dT H; Z moves
!! with the tip (dZ from dq*), so dK_r = Z^T dK Z + dZ^T K Z + Z^T K dZ
!! (likewise M, C), and dphi = dZ y + Z dy with dy from Nelson's method on
!! the reduced problem.
!!
!! Undamped (C = 0): K_T phi = lambda M phi (dsygv), phi^T M phi = 1,
!! frequencies sqrt(lambda) / (2 pi) in Hz, ascending: mode k is the k-th.
!! Damped: the state-space eigenproblem of [0 I; -M^-1 K, -M^-1 C] (dgeev);
!! mode k is the underdamped root s = -zeta w + i w sqrt(1 - zeta^2) whose
!! displacement part best matches (MAC in M) the undamped mode k; its
!! frequency is |s| / (2 pi), its damping ratio -Re(s) / |s|. Mode shapes
!! are the undamped (real) modes in both cases.
!!
!! Sensitivities with respect to model parameters (docs/modal.md):
!! - the equilibrium moves, dq*/dp = -K_T^-1 dR/dp|_q;
!! - the total matrix derivatives dX/dp = dX/dp|_q + (dX/dq)[dq*/dp], X = K_T,
!!   M, C. Every term of the three is linear in its parameter group (EI, EA,
!!   C, rho, m, J, c, eta) or in 1/f (the compliances), so dX/dp|_q is exact
!!   from one more assembly at the same q with the parameter doubled (set to
!!   1 from 0); the directional derivative (dX/dq)[v] along v = dq*/dp is
!!   hand-coded (modal_matrices_dir): the third derivative of the element
!!   strain energy contracted with v (fe_element_tangent_dir: e and chi are
!!   quadratic in q, so it needs their first and second derivatives only),
!!   the hinge springs' (fe_hinge_tangent_dir), the exact tip moment's and
!!   the wire's load stiffness at the fixed T (dT H is added apart), the
!!   rotary inertia's mass block and Kelvin-Voigt damping's C; the
!!   consistent and point masses, drag and the tip forces do not depend on
!!   q. One dense solve per parameter; no difference step (a station's
!!   sampling frame moving with q* is hand-coded too, modal_station_dq);
!! - d lambda = phi^T (dK - lambda dM) phi (undamped), and for a damped root
!!   ds = -psi^T (s^2 dM + s dC + dK) psi / psi^T (2 s M + C) psi (M, C, K
!!   symmetric, so the left eigenvector is the right one, unconjugated);
!! - mode shapes by Nelson's method (1976): (K - lambda M) v = -(dK -
!!   dlambda M - lambda dM) phi with the largest entry of phi held at 0,
!!   dphi = v + c phi, c = -phi^T M v - phi^T dM phi / 2.
!!
!! About a steady spin (spin_rate = Omega /= 0, issue 28): the arm in the hub
!! frame of beamid_hub turning at the constant rate Omega. The equilibrium
!! solves NLT(q) - Q_tip(q) - Omega^2 (c + M q) = 0 (Newton from the static
!! equilibrium under the tip load); the geometrically nonlinear element
!! carries the centrifugal axial force into K_T(q*) (the stiffening), the
!! centrifugal force's own derivative -Omega^2 M softens the in-plane and the
!! axial motion, and the Coriolis force -2 Omega P M v adds the skew
!! gyroscopic matrix G = 2 Omega P M, which couples axial and in-plane
!! motion: M x'' + (C + G) x' + (K_T - Omega^2 M) x = 0, solved in state
!! space like a damped model (coriolis = .false. drops G: the classic
!! uncoupled chordwise model). Shapes stay the modes of (K_T - Omega^2 M, M);
!! without dissipation the damping ratios are 0. Sensitivities about a spin
!! are not available.
module beamid_modal
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK, set_status, ERR_INPUT, ERR_NUMERIC, &
                             fmt_int, fmt_real
    use beamid_model, only: chain_t, chain_from_vector, param_count, param_name, PER_BEAM, &
                            PER_MASS, IB_L, IM_MU, IG_AXIAL_COUPLING, IG_ROOT_FLEX, &
                            IG_R_MOTOR, IG_TAU_MOTOR, param_index_thickness
    use beamid_fe_element, only: FE_W, FE_U, fe_hermite
    use beamid_fe_assembly, only: fe_load_t, fe_mesh_t, fe_band_rows, fe_mass, &
                                  fe_tip_load_jacobian, fe_internal_force, fe_band_to_dense, &
                                  fe_check_dense, FE_MOMENT_EXACT, fe_tangent_dir, &
                                  fe_mass_dir, fe_tip_load_jacobian_dir, fe_wire_jacobian_dir
    use beamid_fe_static, only: fe_newton_opts_t, fe_solve_info_t, fe_solve_static, &
                                fe_solve_wire
    use beamid_fe_assembly, only: fe_wire_tip, fe_wire_jacobian
    use beamid_dynamics, only: dyn_system_t, dyn_setup, dyn_jacobian, FRICTION_SIGN, &
                               dyn_damping_dir
    use beamid_lapack, only: sym_gen_eig, gen_eig, solve_dense
    use beamid_hub, only: hub_forcing_t, hub_setup
    use beamid_fe_assembly, only: fe_tip_load
    implicit none
    private

    public :: modal_spec_t, modal_out_t, modal_solve, modal_station, modal_station_sens
    public :: modal_param_effect, modal_check_stations, SHAPE_N, SHAPE_T, SHAPE_PSI, SHAPE_STRAIN, SHAPE_X, SHAPE_Y
    public :: MP_NONE, MP_LINEAR, MP_INVERSE
    ! the matrices and their directional derivative, for the kernel tests
    public :: modal_system, modal_matrices, modal_matrices_dir, modal_station_dq

    real(dp), parameter :: TWO_PI = 6.283185307179586476925286766559_dp

    !> Quantities of a mode shape sampled at a station (modal_station):
    !! the displacement along the local normal and tangent of the deformed
    !! arm at q*, the change of the tangent angle psi, the change of the gauge
    !! strain e + kappa t/2 (as the observation `strain`, t the beam's strip
    !! thickness), and the displacement along x and y. SHAPE_KAPPA (the
    !! change of the curvature, d strain / d t = its half) is internal: no
    !! station may ask for it.
    integer, parameter :: SHAPE_N = 1, SHAPE_T = 2, SHAPE_PSI = 3, SHAPE_STRAIN = 4, &
                          SHAPE_X = 5, SHAPE_Y = 6, SHAPE_KAPPA = 7
    !> How a parameter enters the modal model: not at all, linearly, as 1/p.
    integer, parameter :: MP_NONE = 0, MP_LINEAR = 1, MP_INVERSE = 2

    !> A modal experiment: mesh and the static load held during the test.
    type :: modal_spec_t
        integer :: elements_per_beam = 4
        type(fe_load_t) :: load
        !> steady hub spin rate Omega (rad/s): modes about the steady spin
        real(dp) :: spin_rate = 0.0_dp
        !> with a spin: keep the Coriolis (gyroscopic) coupling
        logical :: coriolis = .true.
        !> radial wire length Lw (m) held during the test (0: no wire; then
        !! `load` must be zero)
        real(dp) :: wire_length = 0.0_dp
    end type modal_spec_t

    !> What modal_solve returns; mode arrays hold the first nmodes modes.
    type :: modal_out_t
        integer :: n = 0                      !< free unknowns (the model's mode count)
        integer :: nmodes = 0
        logical :: damped = .false.
        real(dp), allocatable :: q(:)         !< static equilibrium q*
        real(dp), allocatable :: lambda(:)    !< undamped eigenvalues omega^2 (all n)
        real(dp), allocatable :: phi(:, :)    !< (n, nmodes) mass-normalized modes
        real(dp), allocatable :: freq(:)      !< (nmodes) natural frequencies, Hz
        real(dp), allocatable :: zeta(:)      !< (nmodes) damping ratios (0 undamped)
        real(dp), allocatable :: dq(:, :)     !< (n, nwrt) dq*/dp
        real(dp), allocatable :: dfreq(:, :)  !< (nmodes, nwrt)
        real(dp), allocatable :: dzeta(:, :)  !< (nmodes, nwrt)
        real(dp), allocatable :: dphi(:, :, :)  !< (n, nmodes, nwrt)
        !> strip thickness per beam (the gauge strain of SHAPE_STRAIN)
        real(dp), allocatable :: thickness(:)
        !> per wrt entry j: b when wrt(j) is thick<b>, else 0
        integer, allocatable :: wrt_thick(:)
        !> the wire's tension T at q* (N; 0 without a wire) and dT/dp (nwrt)
        real(dp) :: tension = 0.0_dp
        real(dp), allocatable :: dtension(:)
    end type modal_out_t

    !> The constraint of a radial wire on the modal problem: q = z y.
    type :: wire_red_t
        logical :: on = .false.
        real(dp) :: tension = 0.0_dp
        integer :: iu = 0, iw = 0, j = 0, ko = 0   !< tip u, w; eliminated, kept
        integer :: col_ko = 0                       !< column of ko in z
        real(dp) :: x(2) = 0.0_dp, rad = 0.0_dp
        real(dp), allocatable :: z(:, :)            !< (n, n - 1)
        real(dp), allocatable :: kr(:, :), mr(:, :), cr(:, :), y(:, :)
        complex(dp), allocatable :: psir(:, :)
    end type wire_red_t

contains

    !> How parameter `index` of a chain of nbeams beams enters the modal
    !! model (MP_*); `why` is set (non-empty) when it cannot be differentiated
    !! here: a length (the mesh depends on it) or a compliance at 0 (a hinge
    !! appears).
    pure subroutine modal_param_effect(chain, index, effect, why)
        type(chain_t), intent(in) :: chain
        integer, intent(in) :: index
        integer, intent(out) :: effect
        character(len=:), allocatable, intent(out) :: why
        integer :: nb, i, which
        nb = chain%nbeams
        why = ''
        effect = MP_LINEAR
        i = index
        if (i <= PER_BEAM*nb) then
            which = mod(i - 1, PER_BEAM) + 1
            if (which == IB_L) then
                effect = MP_NONE
                why = 'sensitivity with respect to '//param_name(nb, index)// &
                      ' (the mesh depends on it) is not available'
            end if
        else if (i <= (PER_BEAM + PER_MASS)*nb) then
            which = mod(i - PER_BEAM*nb - 1, PER_MASS) + 1
            if (which == IM_MU) effect = MP_NONE
        else if (i <= (PER_BEAM + PER_MASS)*nb + nb - 1) then
            effect = MP_INVERSE
            if (.not. (chain%joint_flex(i - (PER_BEAM + PER_MASS)*nb) > 0.0_dp)) then
                why = 'sensitivity with respect to '//param_name(nb, index)// &
                      ' at 0 (a locked joint) is not available: give it a positive compliance'
            end if
        else if (i > param_index_thickness(nb, 0)) then
            effect = MP_NONE    ! the strip thickness: only the gauge's reading
        else
            which = i - (PER_BEAM + PER_MASS)*nb - (nb - 1)
            select case (which)
            case (IG_AXIAL_COUPLING, IG_R_MOTOR, IG_TAU_MOTOR)
                effect = MP_NONE
            case (IG_ROOT_FLEX)
                effect = MP_INVERSE
                if (.not. (chain%root_flex > 0.0_dp)) why = 'sensitivity with respect to '// &
                    'root_flex at 0 (a clamped root) is not available: give it a positive '// &
                    'compliance'
            end select
        end if
    end subroutine modal_param_effect

    !> The dynamic system of the modal model: the chain without friction and
    !! without motor.
    subroutine modal_system(nbeams, params, nepb, sys, stat)
        integer, intent(in) :: nbeams, nepb
        real(dp), intent(in) :: params(:)
        type(dyn_system_t), intent(out) :: sys
        type(status_t), intent(inout) :: stat
        type(chain_t) :: chain
        call chain_from_vector(nbeams, params, chain, stat)
        if (stat%code /= STATUS_OK) return
        chain%friction = 0.0_dp
        call dyn_setup(chain, nepb, 0.0_dp, FRICTION_SIGN, 1.0e-4_dp, sys, stat)
    end subroutine modal_system

    !> Dense K_T (with the tip moment's load stiffness), M(q) and C at rest,
    !! and the internal force NLT(q), at q.
    subroutine modal_matrices(sys, load, q, k, m, c, nlt, tension)
        type(dyn_system_t), intent(in) :: sys
        type(fe_load_t), intent(in) :: load
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: k(:, :), m(:, :), c(:, :), nlt(:)
        !> a radial wire's tension: K_T gains its geometric stiffness T H
        real(dp), intent(in), optional :: tension
        real(dp), allocatable :: kb(:, :), cb(:, :), v(:), b(:), p(:), d(:)
        real(dp) :: x(0), e
        integer :: n
        n = sys%n
        allocate (kb(fe_band_rows(sys%mesh), n), cb(fe_band_rows(sys%mesh), n), v(n), b(n), &
                  p(n), d(n), source=0.0_dp)
        call dyn_jacobian(sys, 0.0_dp, q, v, x, kb, cb, b, p, d, e)
        call fe_tip_load_jacobian(sys%mesh, q, load, -1.0_dp, kb)
        if (present(tension)) then
            if (tension /= 0.0_dp) call fe_wire_jacobian(sys%mesh, q, tension, -1.0_dp, kb)
        end if
        call fe_band_to_dense(kb, sys%mesh%kl, sys%mesh%ku, k)
        call fe_band_to_dense(cb, sys%mesh%kl, sys%mesh%ku, c)
        call fe_mass(sys%mesh, q, .true., kb)
        call fe_band_to_dense(kb, sys%mesh%kl, sys%mesh%ku, m)
        call fe_internal_force(sys%mesh, q, nlt)
    end subroutine modal_matrices

    !> Directional derivatives (dX/dq)[v] at q of the matrices of
    !! modal_matrices, X = K_T, M, C (at the fixed wire tension), hand-coded:
    !! the elements' and the hinge springs' tangents (fe_tangent_dir), the
    !! exact tip moment's load stiffness, the wire's geometric stiffness
    !! T (I - e e^T)/|x| at the fixed T, the rotary inertia's mass block
    !! (fe_mass_dir) and Kelvin-Voigt damping's C (dyn_damping_dir). The
    !! other terms (consistent and point masses, drag, the tip forces) do not
    !! depend on q; the velocity terms of rotary inertia vanish at rest.
    subroutine modal_matrices_dir(sys, load, q, v, tension, dk, dm, dc)
        type(dyn_system_t), intent(in) :: sys
        type(fe_load_t), intent(in) :: load
        real(dp), intent(in) :: q(:), v(:), tension
        real(dp), intent(out) :: dk(:, :), dm(:, :), dc(:, :)
        real(dp), allocatable :: kb(:, :)
        allocate (kb(fe_band_rows(sys%mesh), sys%n))
        call fe_tangent_dir(sys%mesh, q, v, kb)
        call fe_tip_load_jacobian_dir(sys%mesh, q, v, load, -1.0_dp, kb)
        if (tension /= 0.0_dp) call fe_wire_jacobian_dir(sys%mesh, q, v, tension, -1.0_dp, kb)
        call fe_band_to_dense(kb, sys%mesh%kl, sys%mesh%ku, dk)
        call fe_mass_dir(sys%mesh, q, v, kb)
        call fe_band_to_dense(kb, sys%mesh%kl, sys%mesh%ku, dm)
        call dyn_damping_dir(sys, q, v, kb)
        call fe_band_to_dense(kb, sys%mesh%kl, sys%mesh%ku, dc)
    end subroutine modal_matrices_dir

    !> Check the experiment and the request before anything is solved.
    subroutine modal_check(nbeams, params, spec, nmodes, wrt, stat)
        integer, intent(in) :: nbeams, nmodes, wrt(:)
        real(dp), intent(in) :: params(:)
        type(modal_spec_t), intent(in) :: spec
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'modal_solve'
        integer :: j
        if (spec%elements_per_beam < 1) then
            call set_status(stat, ERR_INPUT, where, 'elements_per_beam = '// &
                            fmt_int(spec%elements_per_beam)//', expected at least 1')
            return
        end if
        if (.not. (ieee_is_finite(spec%load%fx) .and. ieee_is_finite(spec%load%fy) .and. &
                   ieee_is_finite(spec%load%moment))) then
            call set_status(stat, ERR_INPUT, where, 'the tip load is not finite')
            return
        end if
        if (spec%load%moment /= 0.0_dp .and. spec%load%moment_form /= FE_MOMENT_EXACT) then
            call set_status(stat, ERR_INPUT, where, 'moment_form = '// &
                            fmt_int(spec%load%moment_form)//' (Eq. 78) with a tip moment of '// &
                            fmt_real(spec%load%moment)//' N m: its load stiffness is not '// &
                            'symmetric, so the modes about it are not those of a '// &
                            'conservative system; expected moment_form = 1 (exact)')
            return
        end if
        if (spec%wire_length /= 0.0_dp) then
            if (.not. (ieee_is_finite(spec%wire_length) .and. spec%wire_length > 0.0_dp)) then
                call set_status(stat, ERR_INPUT, where, 'wire_length = '// &
                                fmt_real(spec%wire_length)//' m, expected a positive length '// &
                                '(or 0: no wire)')
                return
            end if
            if (spec%load%fx /= 0.0_dp .or. spec%load%fy /= 0.0_dp .or. &
                spec%load%moment /= 0.0_dp) then
                call set_status(stat, ERR_INPUT, where, 'a radial wire (wire_length = '// &
                                fmt_real(spec%wire_length)//' m) with a tip load: expected '// &
                                'one or the other')
                return
            end if
            if (spec%spin_rate /= 0.0_dp) then
                call set_status(stat, ERR_INPUT, where, 'a radial wire (wire_length = '// &
                                fmt_real(spec%wire_length)//' m) with spin_rate = '// &
                                fmt_real(spec%spin_rate)//' rad/s: expected no spin about a '// &
                                'wired equilibrium')
                return
            end if
        end if
        if (.not. ieee_is_finite(spec%spin_rate)) then
            call set_status(stat, ERR_INPUT, where, 'spin_rate = '//fmt_real(spec%spin_rate)// &
                            ' rad/s, expected a finite number')
            return
        end if
        if (spec%spin_rate /= 0.0_dp .and. size(wrt) > 0) then
            call set_status(stat, ERR_INPUT, where, 'spin_rate = '//fmt_real(spec%spin_rate)// &
                            ' rad/s with sensitivities (wrt): the sensitivities of the modes '// &
                            'about a steady spin are not available; expected spin_rate = 0 '// &
                            'or no wrt')
            return
        end if
        if (nmodes < 1) then
            call set_status(stat, ERR_INPUT, where, 'nmodes = '//fmt_int(nmodes)// &
                            ', expected at least 1')
            return
        end if
        do j = 1, size(wrt)
            if (wrt(j) < 1 .or. wrt(j) > param_count(nbeams)) then
                call set_status(stat, ERR_INPUT, where, 'wrt('//fmt_int(j)//') = '// &
                                fmt_int(wrt(j))//', expected a parameter index in 1..'// &
                                fmt_int(param_count(nbeams)))
                return
            end if
        end do
        if (size(params) /= param_count(nbeams)) then
            call set_status(stat, ERR_INPUT, where, 'params has '//fmt_int(size(params))// &
                            ' values, expected '//fmt_int(param_count(nbeams)))
        end if
    end subroutine modal_check

    !> Modes of the experiment `spec` for the parameter vector `params` of a
    !! chain of nbeams beams: the first nmodes frequencies (Hz), damping ratios
    !! and mass-normalized shapes, and their derivatives with respect to the
    !! parameters `wrt` (indices into params).
    subroutine modal_solve(nbeams, params, spec, nmodes, wrt, out, stat)
        integer, intent(in) :: nbeams, nmodes, wrt(:)
        real(dp), intent(in) :: params(:)
        type(modal_spec_t), intent(in) :: spec
        type(modal_out_t), intent(out) :: out
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'modal_solve'
        type(dyn_system_t) :: sys
        type(chain_t) :: chain
        type(fe_newton_opts_t) :: opts
        type(fe_solve_info_t) :: info
        real(dp), allocatable :: k(:, :), m(:, :), c(:, :), nlt(:), vec(:, :), g(:, :)
        complex(dp), allocatable :: psi(:, :), s(:)
        type(hub_forcing_t) :: hub
        type(wire_red_t) :: wire
        integer :: n, nw, i, nm
        logical :: spin
        call modal_check(nbeams, params, spec, nmodes, wrt, stat)
        if (stat%code /= STATUS_OK) return
        call chain_from_vector(nbeams, params, chain, stat)
        if (stat%code /= STATUS_OK) return
        call modal_system(nbeams, params, spec%elements_per_beam, sys, stat)
        if (stat%code /= STATUS_OK) return
        n = sys%n
        wire%on = spec%wire_length > 0.0_dp
        nm = merge(n - 1, n, wire%on)
        if (nmodes > nm) then
            call set_status(stat, ERR_INPUT, where, 'mode '//fmt_int(nmodes)//' asked, but '// &
                            'the model of '//fmt_int(spec%elements_per_beam)// &
                            ' elements per beam has '//fmt_int(nm)//' modes')
            return
        end if
        call fe_check_dense(2*n, where, stat)
        if (stat%code /= STATUS_OK) return
        nw = size(wrt)
        out%n = nm
        out%nmodes = nmodes
        out%thickness = chain%thickness
        allocate (out%wrt_thick(nw), source=0)
        do i = 1, nw
            if (wrt(i) > param_index_thickness(nbeams, 0)) &
                out%wrt_thick(i) = wrt(i) - param_index_thickness(nbeams, 0)
        end do
        allocate (out%q(n), out%lambda(n), out%phi(n, nmodes), out%freq(nmodes), &
                  out%zeta(nmodes), out%dq(n, nw), out%dfreq(nmodes, nw), &
                  out%dzeta(nmodes, nw), out%dphi(n, nmodes, nw), &
                  out%dtension(nw), source=0.0_dp)
        allocate (k(n, n), m(n, n), c(n, n), nlt(n), vec(nm, nm))
        out%q = 0.0_dp
        if (wire%on) then
            call fe_solve_wire(sys%mesh, spec%wire_length, out%q, out%tension, opts, info, stat)
        else
            call fe_solve_static(sys%mesh, spec%load, out%q, .false., opts, info, stat)
        end if
        if (stat%code /= STATUS_OK) return
        spin = spec%spin_rate /= 0.0_dp
        allocate (g(n, n), source=0.0_dp)
        if (spin) then
            call hub_setup(sys, spec%spin_rate, 1.0_dp, 'modal_solve (spin_rate = '// &
                           fmt_real(spec%spin_rate)//' rad/s)', hub, stat)
            if (stat%code /= STATUS_OK) return
            call spin_equilibrium(sys, hub, spec%load, out%q, stat)
            if (stat%code /= STATUS_OK) return
        end if
        call modal_matrices(sys, spec%load, out%q, k, m, c, nlt, out%tension)
        out%damped = any(c /= 0.0_dp)
        if (spin) then
            call spin_matrices(sys, hub, out%q, k, g)
            if (.not. spec%coriolis) g = 0.0_dp
        end if
        allocate (s(nmodes), psi(n, nmodes))
        if (wire%on) then
            wire%tension = out%tension
            call wire_reduction(sys, out%q, wire)
            wire%kr = matmul(transpose(wire%z), matmul(k, wire%z))
            wire%mr = matmul(transpose(wire%z), matmul(m, wire%z))
            wire%cr = matmul(transpose(wire%z), matmul(c, wire%z))
            call undamped_modes(wire%kr, wire%mr, out%lambda(1:nm), vec, stat)
            if (stat%code /= STATUS_OK) return
            wire%y = vec(:, 1:nmodes)
            out%phi = matmul(wire%z, wire%y)
            out%freq = sqrt(out%lambda(1:nmodes))/TWO_PI
            allocate (wire%psir(nm, nmodes))
            if (out%damped) then
                call damped_modes(wire%kr, wire%mr, wire%cr, wire%y, s, wire%psir, stat)
                if (stat%code /= STATUS_OK) return
                psi = matmul(wire%z, wire%psir)
                out%freq = abs(s)/TWO_PI
                out%zeta = -real(s, dp)/abs(s)
            end if
        else
            call undamped_modes(k, m, out%lambda, vec, stat)
            if (stat%code /= STATUS_OK) return
            out%phi = vec(:, 1:nmodes)
            out%freq = sqrt(out%lambda(1:nmodes))/TWO_PI
            if (out%damped .or. any(g /= 0.0_dp)) then
                call damped_modes(k, m, c + g, out%phi, s, psi, stat)
                if (stat%code /= STATUS_OK) return
                out%freq = abs(s)/TWO_PI
                if (out%damped) out%zeta = -real(s, dp)/abs(s)
            end if
        end if
        do i = 1, nw
            call modal_sensitivity(chain, sys, spec%load, params, wrt(i), k, m, c, out, s, &
                                   psi, i, wire, stat)
            if (stat%code /= STATUS_OK) return
        end do
    end subroutine modal_solve

    !> The elimination q = z y of the wire's constraint e^T dx = 0 at the tip
    !! of q: the tip unknown j of the larger |e| component follows the other,
    !! ko: q_j = -(x_ko / x_j) q_ko.
    subroutine wire_reduction(sys, q, wire)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: q(:)
        type(wire_red_t), intent(inout) :: wire
        integer :: n, i, col
        n = sys%n
        call fe_wire_tip(sys%mesh, q, wire%iu, wire%iw, wire%x, wire%rad)
        if (abs(wire%x(2)) >= abs(wire%x(1))) then
            wire%j = wire%iw
            wire%ko = wire%iu
        else
            wire%j = wire%iu
            wire%ko = wire%iw
        end if
        allocate (wire%z(n, n - 1), source=0.0_dp)
        col = 0
        do i = 1, n
            if (i == wire%j) cycle
            col = col + 1
            wire%z(i, col) = 1.0_dp
            if (i == wire%ko) wire%col_ko = col
        end do
        wire%z(wire%j, wire%col_ko) = -wire_ratio(wire, wire%x)
    end subroutine wire_reduction

    !> x_ko / x_j of the tip position x (x(1) along u, x(2) along w).
    pure real(dp) function wire_ratio(wire, x) result(ratio)
        type(wire_red_t), intent(in) :: wire
        real(dp), intent(in) :: x(2)
        if (wire%j == wire%iw) then
            ratio = x(1)/x(2)
        else
            ratio = x(2)/x(1)
        end if
    end function wire_ratio

    !> The equilibrium in the hub frame turning at hub%ws: Newton on
    !! NLT(q) - Q_tip(q) - F_hub(q) = 0 from q (the static equilibrium under
    !! the tip load), with the tangent K_T - dQ/dq - Omega^2 M.
    subroutine spin_equilibrium(sys, hub, load, q, stat)
        type(dyn_system_t), intent(in) :: sys
        type(hub_forcing_t), intent(in) :: hub
        type(fe_load_t), intent(in) :: load
        real(dp), intent(inout) :: q(:)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: k(:, :), m(:, :), c(:, :), g(:, :), nlt(:), f(:), qv(:), &
                                 r(:, :), v(:)
        real(dp) :: power, step
        integer :: n, it
        n = size(q)
        allocate (k(n, n), m(n, n), c(n, n), g(n, n), nlt(n), f(n), qv(n), r(n, 1), v(n), &
                  source=0.0_dp)
        do it = 1, 60
            f = 0.0_dp
            call hub%apply(2.0_dp*hub%period, q, v, f, power)
            call fe_tip_load(sys%mesh, q, load, qv)
            call modal_matrices(sys, load, q, k, m, c, nlt)
            call spin_matrices(sys, hub, q, k, g)
            r(:, 1) = -(nlt - qv - f)
            call solve_dense(k, r, stat)
            if (stat%code /= STATUS_OK) return
            q = q + r(:, 1)
            step = maxval(abs(r(:, 1)))
            if (.not. ieee_is_finite(step)) exit
            if (step <= 1.0e-13_dp*max(1.0_dp, maxval(abs(q)))) return
        end do
        call set_status(stat, ERR_NUMERIC, 'modal_solve', 'spin_rate = '// &
                        fmt_real(hub%ws)//' rad/s: the equilibrium in the hub frame did not '// &
                        'converge in 60 Newton steps (last step '//fmt_real(step)//')')
    end subroutine spin_equilibrium

    !> k += -Omega^2 M (the centrifugal force's derivative) and g = 2 Omega
    !! P M (the Coriolis force's), dense, at the steady spin hub%ws.
    subroutine spin_matrices(sys, hub, q, k, g)
        type(dyn_system_t), intent(in) :: sys
        type(hub_forcing_t), intent(in) :: hub
        real(dp), intent(in) :: q(:)
        real(dp), intent(inout) :: k(:, :)
        real(dp), intent(out) :: g(:, :)
        real(dp), allocatable :: kb(:, :), cb(:, :), kd(:, :), v(:)
        integer :: n
        n = size(q)
        allocate (kb(fe_band_rows(sys%mesh), n), cb(fe_band_rows(sys%mesh), n), kd(n, n), &
                  v(n), source=0.0_dp)
        call hub%jacobian(2.0_dp*hub%period, q, v, sys%mesh%kl, sys%mesh%ku, kb, cb)
        call fe_band_to_dense(kb, sys%mesh%kl, sys%mesh%ku, kd)
        k = k + kd
        call fe_band_to_dense(cb, sys%mesh%kl, sys%mesh%ku, g)
    end subroutine spin_matrices

    !> K phi = lambda M phi; every lambda must be positive (a stable
    !! equilibrium).
    subroutine undamped_modes(k, m, lambda, vec, stat)
        real(dp), intent(in) :: k(:, :), m(:, :)
        real(dp), intent(out) :: lambda(:), vec(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: mm(:, :)
        vec = k
        mm = m
        call sym_gen_eig(vec, mm, lambda, stat)
        if (stat%code /= STATUS_OK) return
        if (lambda(1) <= 0.0_dp) then
            call set_status(stat, ERR_NUMERIC, 'modal_solve', 'the tangent stiffness at '// &
                            'the equilibrium has the eigenvalue '//fmt_real(lambda(1))// &
                            ': the equilibrium is not stable, it has no vibration modes')
        end if
    end subroutine undamped_modes

    !> The damped roots s (Im s > 0) and their displacement eigenvectors psi
    !! paired with the undamped modes phi (MAC in M).
    subroutine damped_modes(k, m, c, phi, s, psi, stat)
        real(dp), intent(in) :: k(:, :), m(:, :), c(:, :), phi(:, :)
        complex(dp), intent(out) :: s(:), psi(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: a(:, :), mk(:, :), mm(:, :), wr(:), wi(:), vr(:, :)
        complex(dp), allocatable :: z(:), mz(:)
        real(dp) :: best, mac, den
        integer :: n, i, j, jbest
        n = size(k, 1)
        allocate (a(2*n, 2*n), mk(n, 2*n), wr(2*n), wi(2*n), vr(2*n, 2*n), z(n), mz(n))
        mk(:, 1:n) = k
        mk(:, n + 1:) = c
        mm = m
        call solve_dense(mm, mk, stat)
        if (stat%code /= STATUS_OK) return
        a = 0.0_dp
        do i = 1, n
            a(i, n + i) = 1.0_dp
        end do
        a(n + 1:, :) = -mk
        call gen_eig(a, wr, wi, vr, stat)
        if (stat%code /= STATUS_OK) return
        do i = 1, size(s)
            best = 0.0_dp
            jbest = 0
            do j = 1, 2*n - 1
                if (.not. (wi(j) > 0.0_dp)) cycle
                z = cmplx(vr(1:n, j), vr(1:n, j + 1), dp)
                mz = matmul(m, z)
                den = real(dot_product(z, mz), dp)
                if (.not. (den > 0.0_dp)) cycle
                mac = abs(dot_product(phi(:, i), mz))**2/den
                if (mac > best) then
                    best = mac
                    jbest = j
                end if
            end do
            if (jbest == 0 .or. best < 0.5_dp) then
                call set_status(stat, ERR_NUMERIC, 'modal_solve', 'mode '//fmt_int(i)// &
                                ' has no underdamped root of the damped model (best MAC '// &
                                fmt_real(best)//'): it is overdamped')
                return
            end if
            s(i) = cmplx(wr(jbest), wi(jbest), dp)
            psi(:, i) = cmplx(vr(1:n, jbest), vr(1:n, jbest + 1), dp)
        end do
    end subroutine damped_modes

    !> Derivatives with respect to parameter `index` (column j of out).
    subroutine modal_sensitivity(chain, sys, load, params, index, k, m, c, out, s, psi, j, &
                                 wire, stat)
        type(chain_t), intent(in) :: chain
        type(dyn_system_t), intent(in) :: sys
        type(fe_load_t), intent(in) :: load
        real(dp), intent(in) :: params(:), k(:, :), m(:, :), c(:, :)
        integer, intent(in) :: index, j
        type(modal_out_t), intent(inout) :: out
        complex(dp), intent(in) :: s(:), psi(:, :)
        type(wire_red_t), intent(in) :: wire
        type(status_t), intent(inout) :: stat
        type(dyn_system_t) :: sys2
        real(dp), allocatable :: dz(:, :), dkr(:, :), dmr(:, :), dcr(:, :), dy(:)
        real(dp) :: dx(2), dratio, e(2), hw(2, 2)
        real(dp), allocatable :: p2(:), k2(:, :), m2(:, :), c2(:, :), f1(:), f2(:), dk(:, :), &
                                 dm(:, :), dc(:, :), kk(:, :), rhs(:, :), kp(:, :), mp(:, :), &
                                 cp(:, :)
        character(len=:), allocatable :: why
        real(dp) :: p, scale, dlam, lam
        complex(dp) :: ds, num, den
        integer :: effect, n, i
        n = sys%n
        call modal_param_effect(chain, index, effect, why)
        if (len(why) > 0) then
            call set_status(stat, ERR_INPUT, 'modal_solve', why)
            return
        end if
        if (effect == MP_NONE) return
        allocate (k2(n, n), m2(n, n), c2(n, n), f1(n), f2(n), kp(n, n), mp(n, n), cp(n, n))
        ! dX/dp at the fixed q from X(p) and X(p2)
        p = params(index)
        p2 = params
        if (p == 0.0_dp) then
            p2(index) = 1.0_dp
            scale = 1.0_dp
        else
            p2(index) = 2.0_dp*p
            scale = 1.0_dp/p
            if (effect == MP_INVERSE) scale = -2.0_dp/p
        end if
        call modal_system(chain%nbeams, p2, sys%mesh%nel/chain%nbeams, sys2, stat)
        if (stat%code /= STATUS_OK) return
        call modal_matrices(sys2, load, out%q, k2, m2, c2, f2, out%tension)
        call fe_internal_force(sys%mesh, out%q, f1)
        if (effect == MP_INVERSE) then
            ! X = A/p + B: X(p) - X(2p) = A/(2p), dX/dp = -A/p^2 = -(2/p)(X(p) - X(2p))
            dk = scale*(k - k2)
            dm = scale*(m - m2)
            dc = scale*(c - c2)
            f2 = scale*(f1 - f2)
        else
            dk = scale*(k2 - k)
            dm = scale*(m2 - m)
            dc = scale*(c2 - c)
            f2 = scale*(f2 - f1)
        end if
        ! the equilibrium moves: K_T dq = -dR/dp (the load does not depend on p);
        ! with a wire, the bordered tangent gives (dq, dT) on the circle
        if (wire%on) then
            allocate (kk(n + 1, n + 1), rhs(n + 1, 1), source=0.0_dp)
            kk(1:n, 1:n) = k
            kk(wire%iu, n + 1) = wire%x(1)/wire%rad
            kk(wire%iw, n + 1) = wire%x(2)/wire%rad
            kk(n + 1, 1:n) = kk(1:n, n + 1)
        else
            kk = k
            allocate (rhs(n, 1), source=0.0_dp)
        end if
        rhs(1:n, 1) = -f2
        call solve_dense(kk, rhs, stat)
        if (stat%code /= STATUS_OK) return
        out%dq(:, j) = rhs(1:n, 1)
        if (wire%on) out%dtension(j) = rhs(n + 1, 1)
        if (maxval(abs(rhs(1:n, 1))) > 0.0_dp) then
            call modal_matrices_dir(sys, load, out%q, rhs(1:n, 1), out%tension, kp, mp, cp)
            dk = dk + kp
            dm = dm + mp
            dc = dc + cp
        end if
        if (wire%on) then
            ! the tension's change: dT H
            e = wire%x/wire%rad
            hw(1, :) = [1.0_dp - e(1)*e(1), -e(1)*e(2)]
            hw(2, :) = [-e(1)*e(2), 1.0_dp - e(2)*e(2)]
            hw = out%dtension(j)*hw/wire%rad
            dk(wire%iu, wire%iu) = dk(wire%iu, wire%iu) + hw(1, 1)
            dk(wire%iu, wire%iw) = dk(wire%iu, wire%iw) + hw(1, 2)
            dk(wire%iw, wire%iu) = dk(wire%iw, wire%iu) + hw(2, 1)
            dk(wire%iw, wire%iw) = dk(wire%iw, wire%iw) + hw(2, 2)
            ! the constraint turns with the tip: dz, and the reduced derivatives
            dx = [out%dq(wire%iu, j), out%dq(wire%iw, j)]
            if (wire%j == wire%iw) then
                dratio = (dx(1)*wire%x(2) - wire%x(1)*dx(2))/wire%x(2)**2
            else
                dratio = (dx(2)*wire%x(1) - wire%x(2)*dx(1))/wire%x(1)**2
            end if
            allocate (dz(n, n - 1), source=0.0_dp)
            dz(wire%j, wire%col_ko) = -dratio
            dkr = reduced_derivative(wire%z, dz, k, dk)
            dmr = reduced_derivative(wire%z, dz, m, dm)
            dcr = reduced_derivative(wire%z, dz, c, dc)
            allocate (dy(n - 1))
            do i = 1, out%nmodes
                lam = out%lambda(i)
                associate (yy => wire%y(:, i))
                    dlam = dot_product(yy, matmul(dkr, yy) - lam*matmul(dmr, yy))
                    out%dfreq(i, j) = dlam/(2.0_dp*sqrt(lam))/TWO_PI
                    call nelson(wire%kr, wire%mr, dkr, dmr, lam, dlam, yy, dy, stat)
                    if (stat%code /= STATUS_OK) return
                    out%dphi(:, i, j) = matmul(dz, yy) + matmul(wire%z, dy)
                end associate
                if (out%damped) then
                    associate (z => wire%psir(:, i), si => s(i))
                        num = sum(z*matmul(si*si*dmr + si*dcr + dkr, z))
                        den = sum(z*matmul(2.0_dp*si*wire%mr + wire%cr, z))
                        ds = -num/den
                        out%dfreq(i, j) = real(conjg(si)*ds, dp)/abs(si)/TWO_PI
                        out%dzeta(i, j) = -(real(ds, dp)*abs(si) - real(si, dp)* &
                                            (real(conjg(si)*ds, dp)/abs(si)))/abs(si)**2
                    end associate
                end if
            end do
            return
        end if
        do i = 1, out%nmodes
            lam = out%lambda(i)
            associate (ph => out%phi(:, i))
                dlam = dot_product(ph, matmul(dk, ph) - lam*matmul(dm, ph))
                out%dfreq(i, j) = dlam/(2.0_dp*sqrt(lam))/TWO_PI
                call nelson(k, m, dk, dm, lam, dlam, ph, out%dphi(:, i, j), stat)
                if (stat%code /= STATUS_OK) return
            end associate
            if (out%damped) then
                associate (z => psi(:, i), si => s(i))
                    num = sum(z*matmul(si*si*dm + si*dc + dk, z))
                    den = sum(z*matmul(2.0_dp*si*m + c, z))
                    ds = -num/den
                    out%dfreq(i, j) = real(conjg(si)*ds, dp)/abs(si)/TWO_PI
                    out%dzeta(i, j) = -(real(ds, dp)*abs(si) - real(si, dp)* &
                                        (real(conjg(si)*ds, dp)/abs(si)))/abs(si)**2
                end associate
            end if
        end do
    end subroutine modal_sensitivity

    !> d(z^T a z) = z^T da z + dz^T a z + z^T a dz.
    pure function reduced_derivative(z, dz, a, da) result(dr)
        real(dp), intent(in) :: z(:, :), dz(:, :), a(:, :), da(:, :)
        real(dp), allocatable :: dr(:, :), az(:, :)
        az = matmul(a, z)
        dr = matmul(transpose(z), matmul(da, z)) + matmul(transpose(dz), az)
        dr = dr + transpose(matmul(transpose(dz), az))
    end function reduced_derivative

    !> Nelson's method for the derivative of the mass-normalized mode phi of
    !! the distinct eigenvalue lam.
    subroutine nelson(k, m, dk, dm, lam, dlam, phi, dphi, stat)
        real(dp), intent(in) :: k(:, :), m(:, :), dk(:, :), dm(:, :), lam, dlam, phi(:)
        real(dp), intent(out) :: dphi(:)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: a(:, :), rhs(:, :)
        integer :: n, im
        real(dp) :: cc
        n = size(phi)
        a = k - lam*m
        allocate (rhs(n, 1))
        rhs(:, 1) = -(matmul(dk, phi) - dlam*matmul(m, phi) - lam*matmul(dm, phi))
        im = maxloc(abs(phi), 1)
        a(im, :) = 0.0_dp
        a(:, im) = 0.0_dp
        a(im, im) = 1.0_dp
        rhs(im, 1) = 0.0_dp
        call solve_dense(a, rhs, stat)
        if (stat%code /= STATUS_OK) return
        cc = -dot_product(phi, matmul(m, rhs(:, 1))) - 0.5_dp*dot_product(phi, matmul(dm, phi))
        dphi = rhs(:, 1) + cc*phi
    end subroutine nelson

    !> A mode shape `vec` (free unknowns) sampled at a station (beam b, arc
    !! length s from its root) of the arm deformed to q: SHAPE_* (linear in
    !! vec: the change of the quantity along vec); t the strip thickness of
    !! that beam (SHAPE_STRAIN).
    pure real(dp) function modal_station(mesh, q, vec, kind, beam, s, t) result(value)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:), vec(:), s, t
        integer, intent(in) :: kind, beam
        real(dp) :: jq(6), jv(6), u1, w1, u2, w2, du, dw, du1, dw1, du2, dw2, p1, r2, chi, &
                    dchi, dr2, dkap
        logical :: ok
        value = 0.0_dp
        call station_jet(mesh, beam, s, q, ok, jq)
        if (.not. ok) return
        call station_jet(mesh, beam, s, vec, ok, jv)
        u1 = jq(3); w1 = jq(4); u2 = jq(5); w2 = jq(6)
        du = jv(1); dw = jv(2); du1 = jv(3); dw1 = jv(4); du2 = jv(5); dw2 = jv(6)
        p1 = 1.0_dp + u1
        r2 = p1*p1 + w1*w1
        select case (kind)
        case (SHAPE_N)
            value = (-w1*du + p1*dw)/sqrt(r2)
        case (SHAPE_T)
            value = (p1*du + w1*dw)/sqrt(r2)
        case (SHAPE_PSI)
            value = (p1*dw1 - w1*du1)/r2
        case (SHAPE_STRAIN)
            chi = w2*p1 - w1*u2
            dchi = dw2*p1 + w2*du1 - dw1*u2 - w1*du2
            dr2 = 2.0_dp*(p1*du1 + w1*dw1)
            dkap = dchi/r2**1.5_dp - 1.5_dp*chi/r2**2.5_dp*dr2
            value = p1*du1 + w1*dw1 + 0.5_dp*t*dkap
        case (SHAPE_KAPPA)
            chi = w2*p1 - w1*u2
            dchi = dw2*p1 + w2*du1 - dw1*u2 - w1*du2
            dr2 = 2.0_dp*(p1*du1 + w1*dw1)
            value = dchi/r2**1.5_dp - 1.5_dp*chi/r2**2.5_dp*dr2
        case (SHAPE_X)
            value = du
        case (SHAPE_Y)
            value = dw
        end select
    end function modal_station

    !> The values and arc-length derivatives of a nodal vector v at the
    !! station (beam, s): jet = [u, w, u', w', u'', w''] (the element holding
    !! s, the cubic Hermite functions of Eq. 76); ok = .false. for a beam
    !! the mesh does not have.
    pure subroutine station_jet(mesh, beam, s, v, ok, jet)
        type(fe_mesh_t), intent(in) :: mesh
        integer, intent(in) :: beam
        real(dp), intent(in) :: s, v(:)
        logical, intent(out) :: ok
        real(dp), intent(out) :: jet(6)
        real(dp) :: f(4), f1(4), f2(4), h, zeta, ve(8)
        integer :: el, first, nel_b, idx, a, j
        jet = 0.0_dp
        first = findloc(mesh%beam, beam, 1)
        ok = first /= 0
        if (.not. ok) return
        nel_b = count(mesh%beam == beam)
        h = mesh%h(first)
        idx = min(max(int(s/h), 0), nel_b - 1)
        el = first + idx
        zeta = min(max(s/h - real(idx, dp), 0.0_dp), 1.0_dp)
        call fe_hermite(zeta, h, f, f1, f2)
        ve = 0.0_dp
        do a = 1, 8
            j = mesh%el_free(a, el)
            if (j /= 0) ve(a) = v(j)
        end do
        jet = [dot_product(f, ve(FE_U)), dot_product(f, ve(FE_W)), dot_product(f1, ve(FE_U)), &
               dot_product(f1, ve(FE_W)), dot_product(f2, ve(FE_U)), dot_product(f2, ve(FE_W))]
    end subroutine station_jet

    !> Directional derivative of modal_station(mesh, q, vec, ...) with respect
    !! to q along dq at the fixed vec (the sampling frame moving with q*),
    !! hand-coded: with p1 = 1 + u', r2 = p1^2 + w'^2 and the changes
    !! (d.) of u', w', u'', w'' along dq, the derivative of each SHAPE_* of
    !! modal_station by the product and the quotient rules.
    pure real(dp) function modal_station_dq(mesh, q, dq, vec, kind, beam, s, t) result(value)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:), dq(:), vec(:), s, t
        integer, intent(in) :: kind, beam
        real(dp) :: jq(6), jv(6), jd(6), u1, w1, u2, w2, du, dw, du1, dw1, du2, dw2, p1, r2, &
                    chi, dchi, dr2, su1, sw1, su2, sw2, sr2, schi, sdchi, sdr2, base
        logical :: ok
        value = 0.0_dp
        call station_jet(mesh, beam, s, q, ok, jq)
        if (.not. ok) return
        call station_jet(mesh, beam, s, vec, ok, jv)
        call station_jet(mesh, beam, s, dq, ok, jd)
        u1 = jq(3); w1 = jq(4); u2 = jq(5); w2 = jq(6)
        du = jv(1); dw = jv(2); du1 = jv(3); dw1 = jv(4); du2 = jv(5); dw2 = jv(6)
        ! the changes of q's u', w', u'', w'' along dq
        su1 = jd(3); sw1 = jd(4); su2 = jd(5); sw2 = jd(6)
        p1 = 1.0_dp + u1
        r2 = p1*p1 + w1*w1
        sr2 = 2.0_dp*(p1*su1 + w1*sw1)
        select case (kind)
        case (SHAPE_N)
            base = -w1*du + p1*dw
            value = (-sw1*du + su1*dw)/sqrt(r2) - 0.5_dp*base*sr2/r2**1.5_dp
        case (SHAPE_T)
            base = p1*du + w1*dw
            value = (su1*du + sw1*dw)/sqrt(r2) - 0.5_dp*base*sr2/r2**1.5_dp
        case (SHAPE_PSI)
            base = p1*dw1 - w1*du1
            value = (su1*dw1 - sw1*du1)/r2 - base*sr2/(r2*r2)
        case (SHAPE_STRAIN, SHAPE_KAPPA)
            chi = w2*p1 - w1*u2
            dchi = dw2*p1 + w2*du1 - dw1*u2 - w1*du2
            dr2 = 2.0_dp*(p1*du1 + w1*dw1)
            schi = sw2*p1 + w2*su1 - sw1*u2 - w1*su2
            sdchi = dw2*su1 + sw2*du1 - dw1*su2 - sw1*du2
            sdr2 = 2.0_dp*(su1*du1 + sw1*dw1)
            ! d[dchi r2^-1.5 - 1.5 chi dr2 r2^-2.5]
            value = sdchi/r2**1.5_dp - 1.5_dp*dchi*sr2/r2**2.5_dp &
                    - 1.5_dp*(schi*dr2 + chi*sdr2)/r2**2.5_dp &
                    + 3.75_dp*chi*dr2*sr2/r2**3.5_dp
            if (kind == SHAPE_STRAIN) value = su1*du1 + sw1*dw1 + 0.5_dp*t*value
        case default
            value = 0.0_dp   ! SHAPE_X, SHAPE_Y: the displacements, linear in vec only
        end select
    end function modal_station_dq

    !> Derivative of modal_station of mode i with respect to parameter j of
    !! `out`: the shape's derivative sampled at q*, plus the change of the
    !! sampling (the local frame) as q* moves (modal_station_dq along
    !! dq*/dp); for the strip thickness of
    !! the station's beam, the gauge strain's kappa/2.
    pure real(dp) function modal_station_sens(mesh, out, i, j, kind, beam, s) result(d)
        type(fe_mesh_t), intent(in) :: mesh
        type(modal_out_t), intent(in) :: out
        integer, intent(in) :: i, j, kind, beam
        real(dp), intent(in) :: s
        real(dp) :: t
        t = out%thickness(beam)
        d = modal_station(mesh, out%q, out%dphi(:, i, j), kind, beam, s, t)
        d = d + modal_station_dq(mesh, out%q, out%dq(:, j), out%phi(:, i), kind, beam, s, t)
        if (kind == SHAPE_STRAIN .and. out%wrt_thick(j) == beam) &
            d = d + 0.5_dp*modal_station(mesh, out%q, out%phi(:, i), SHAPE_KAPPA, beam, s, t)
    end function modal_station_sens

    !> Each station (kind SHAPE_*, beam, s) must name a known kind, a beam of
    !! the mesh and an arc length within that beam.
    pure subroutine modal_check_stations(mesh, kinds, beams, s, stat)
        type(fe_mesh_t), intent(in) :: mesh
        integer, intent(in) :: kinds(:), beams(:)
        real(dp), intent(in) :: s(:)
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'modal_station'
        integer :: k
        real(dp) :: length
        do k = 1, size(kinds)
            if (kinds(k) < SHAPE_N .or. kinds(k) > SHAPE_Y) then
                call set_status(stat, ERR_INPUT, where, 'station '//fmt_int(k)//' kind = '// &
                                fmt_int(kinds(k))//', expected 1..6 (n, t, psi, strain, x, y)')
                return
            end if
            if (beams(k) < 1 .or. beams(k) > mesh%nbeams) then
                call set_status(stat, ERR_INPUT, where, 'station '//fmt_int(k)//' beam = '// &
                                fmt_int(beams(k))//', expected 1..'//fmt_int(mesh%nbeams))
                return
            end if
            length = sum(mesh%h, mask=mesh%beam == beams(k))
            if (.not. (s(k) >= 0.0_dp .and. s(k) <= length*(1.0_dp + 1.0e-12_dp))) then
                call set_status(stat, ERR_INPUT, where, 'station '//fmt_int(k)//' s = '// &
                                fmt_real(s(k))//' on beam '//fmt_int(beams(k))// &
                                ', expected an arc length in [0, '//fmt_real(length)//']')
                return
            end if
        end do
    end subroutine modal_check_stations

end module beamid_modal
