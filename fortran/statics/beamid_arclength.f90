!> Large static deformation of a clamped beam chain in arc-length coordinates
!! (dissertation Chapter III), with parametric sensitivities (Eq. 40-51).
!!
!! State along the arc (absolute tangent angle psi, Eq. 12-15):
!!     z = (x, y, psi, k, Q, N)
!! with curvature k = dpsi/ds, shear Q and axial force N. Equilibrium with the
!! cubic material law M = EI k + C k^3 (Eq. 16) and Q = -dM/ds (Eq. 10):
!!     x' = cos psi,  y' = sin psi,  psi' = k,
!!     k' = -Q / (EI + 3 C k^2),
!!     Q' = -a k N,   N' = k Q.
!! The normal-force balance Q' = -a k N carries the parameter a =
!! `axial_coupling`: a = 0 is the dissertation's shear-only form (Eq. 9,
!! dQ/ds = 0), which produced Tables 2-5; a = 1 is the exact (Kirchhoff)
!! elastica, for which (Q, N) are the normal and tangential components of a
!! constant force vector. See docs/theory.md.
!!
!! Joints transmit M, Q, N; the curvature jumps so that the moment is
!! continuous (Eq. 20) and a compliant joint adds a kink psi+ = psi- + f M
!! (`elbow_flex`); a compliant root starts at psi(0) = f_root M(0).
!!
!! Boundary value problem by shooting (Section 3.1.4): the unknowns
!! u = (k(0), Q(0), N(0) [, wire tension T]) are found by Newton on the tip
!! conditions, with the state-transition matrix dz/du integrated alongside
!! (Eq. 30-35). Tip conditions: M(L) = M_tip (Eq. 23 when zero), Q(L) = P.n,
!! N(L) = P.t for the tip force P (Eq. 27 with cos for sin, docs/theory.md);
!! the radial wire adds |r_tip| = Lw (Eq. 22) with P = -T r_tip/|r_tip|.
!! Sensitivities to named parameters use the implicit function theorem on the
!! tip conditions (Eq. 44-51) and parametric transition matrices (Eq. 41, 43).
!!
!! Integration: Dormand-Prince 5(4) with error control on z; the variational
!! columns are integrated with the accepted steps of z, so Newton sees the
!! exact derivative of the discrete map.
module beamid_arclength
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_value, ieee_quiet_nan
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_INPUT, ERR_NO_CONVERGENCE, &
                             ERR_NUMERIC, ERR_SINGULAR, fmt_real, fmt_int, STATUS_OK
    use beamid_model, only: chain_t, param_count, param_index_beam, param_index_joint_flex, &
                            param_index_global, IB_L, IB_EI, IB_C, IG_AXIAL_COUPLING, &
                            IG_ROOT_FLEX
    use beamid_lapack, only: solve_dense
    implicit none
    private

    public :: static_load_t, static_options_t, static_solution_t
    public :: solve_static, static_shape, validate_static_load, static_stations
    public :: static_load_from_values, static_options_from_tol
    public :: LOAD_TIP, LOAD_WIRE, NOUT
    public :: OUT_X_TIP, OUT_Y_TIP, OUT_TIP_ANGLE, OUT_WIRE_FORCE, OUT_X_ELBOW, &
              OUT_Y_ELBOW, OUT_ELBOW_ANGLE, OUT_ROOT_MOMENT

    integer, parameter :: LOAD_TIP = 1   !< fixed-direction tip force (fx, fy) and tip moment
    integer, parameter :: LOAD_WIRE = 2  !< radial wire of length Lw from tip to root (Eq. 22)

    integer, parameter :: NOUT = 8
    integer, parameter :: OUT_X_TIP = 1, OUT_Y_TIP = 2, OUT_TIP_ANGLE = 3, &
                          OUT_WIRE_FORCE = 4, OUT_X_ELBOW = 5, OUT_Y_ELBOW = 6, &
                          OUT_ELBOW_ANGLE = 7, OUT_ROOT_MOMENT = 8

    integer, parameter :: NZ = 6
    integer, parameter :: IX = 1, IY = 2, IPSI = 3, IK = 4, IQ = 5, IN = 6
    integer, parameter :: NSHOOT = 3  !< shooting unknowns carried by the ODE: k0, Q0, N0

    !> Loosest integration tolerance of the early Newton shots (a residual of
    !! 0.3 or more); below that the shots are integrated to 1e-3 r^2.
    real(dp), parameter :: LOOSE_TOL_MAX = 1.0e-4_dp

    !> Column kinds of the variational matrix: how a column is forced.
    integer, parameter :: COL_FREE = 0, COL_EI = 1, COL_C = 2, COL_A = 3

    ! Dormand-Prince 5(4) tableau
    real(dp), parameter :: a21 = 1.0_dp/5
    real(dp), parameter :: a31 = 3.0_dp/40, a32 = 9.0_dp/40
    real(dp), parameter :: a41 = 44.0_dp/45, a42 = -56.0_dp/15, a43 = 32.0_dp/9
    real(dp), parameter :: a51 = 19372.0_dp/6561, a52 = -25360.0_dp/2187, &
                           a53 = 64448.0_dp/6561, a54 = -212.0_dp/729
    real(dp), parameter :: a61 = 9017.0_dp/3168, a62 = -355.0_dp/33, &
                           a63 = 46732.0_dp/5247, a64 = 49.0_dp/176, &
                           a65 = -5103.0_dp/18656
    real(dp), parameter :: b1 = 35.0_dp/384, b3 = 500.0_dp/1113, b4 = 125.0_dp/192, &
                           b5 = -2187.0_dp/6784, b6 = 11.0_dp/84
    real(dp), parameter :: e1 = 71.0_dp/57600, e3 = -71.0_dp/16695, e4 = 71.0_dp/1920, &
                           e5 = -17253.0_dp/339200, e6 = 22.0_dp/525, e7 = -1.0_dp/40

    !> A static load case.
    type :: static_load_t
        integer :: kind = LOAD_TIP
        real(dp) :: fx = 0.0_dp          !< tip force, global x (N)
        real(dp) :: fy = 0.0_dp          !< tip force, global y (N)
        real(dp) :: moment = 0.0_dp      !< tip moment (N m), counter-clockwise
        real(dp) :: wire_length = 0.0_dp !< radial wire length Lw (m)
    end type static_load_t

    !> Solver controls.
    type :: static_options_t
        real(dp) :: tol = 1.0e-9_dp           !< integration error tolerance (relative)
        !> scaled residual at convergence; 0: ten times tol (the integration
        !! error bounds what a tighter Newton tolerance could achieve)
        real(dp) :: newton_tol = 0.0_dp
        integer :: max_newton = 30            !< Newton iterations per load level
        integer :: max_load_steps = 400       !< continuation steps before giving up
        integer :: max_rk_steps = 200000      !< integration steps per shot
    end type static_options_t

    !> Converged solution with outputs and their sensitivities.
    type :: static_solution_t
        real(dp) :: outputs(NOUT) = 0.0_dp
        !> d outputs / d params(wrt(j)), NOUT x size(wrt)
        real(dp), allocatable :: doutputs(:, :)
        !> shooting unknowns k(0), Q(0), N(0), T (T = 0 without a wire)
        real(dp) :: unknowns(4) = 0.0_dp
        !> their derivatives d unknowns / d params(wrt(j)), nu x size(wrt)
        real(dp), allocatable :: dunknowns(:, :)
        integer :: newton_iterations = 0
        integer :: load_steps = 0
        real(dp) :: residual = 0.0_dp
    end type static_solution_t

    !> Everything the shooting needs besides the unknowns.
    type :: problem_t
        type(chain_t) :: chain
        type(static_load_t) :: load
        real(dp) :: total_length = 0.0_dp
        real(dp) :: force_scale = 1.0_dp, moment_scale = 1.0_dp
        real(dp) :: load_factor = 1.0_dp   !< continuation factor on the tip load
        integer :: nu = 3                  !< number of unknowns (4 with the wire)
    end type problem_t

    !> Work arrays of the shots, kept from one shot to the next so that the
    !! integration loop does not allocate; shoot sizes them for its columns.
    type :: shot_work_t
        real(dp), allocatable :: v(:, :)        !< NZ x ncol, running columns
        real(dp), allocatable :: w(:, :, :)     !< NZ x ncol x 6, stage slopes of v
        real(dp), allocatable :: vs(:, :)       !< NZ x ncol, stage argument
        integer, allocatable :: colkind(:)
        real(dp), allocatable :: vk_old(:), ddelta(:), vq_old(:), vn_old(:)
    end type shot_work_t

    !> Result of one shot.
    type :: shot_t
        real(dp) :: z_end(NZ) = 0.0_dp
        real(dp), allocatable :: v_end(:, :)        !< NZ x ncol
        real(dp), allocatable :: z_joint(:, :)      !< NZ x nbeams (end of each beam)
        real(dp), allocatable :: v_joint(:, :, :)   !< NZ x ncol x nbeams
        integer :: steps = 0
        type(shot_work_t) :: work
    end type shot_t

contains

    ! ------------------------------------------------------------------ material

    !> Bending stiffness dM/dk = EI + 3 C k^2 of the cubic law (Eq. 16).
    pure real(dp) function tangent_stiffness(ei, c, k)
        real(dp), intent(in) :: ei, c, k
        tangent_stiffness = ei + 3.0_dp*c*k*k
    end function tangent_stiffness

    !> Curvature on the branch through k = 0 with EI k + C k^3 = M.
    pure subroutine curvature_from_moment(ei, c, moment, k, ok)
        real(dp), intent(in) :: ei, c, moment
        real(dp), intent(out) :: k
        logical, intent(out) :: ok
        real(dp) :: f, d, kmax, mmax
        integer :: it
        ok = .true.
        k = moment/ei
        if (c == 0.0_dp) return
        if (c < 0.0_dp) then
            ! softening: the branch ends where EI + 3 C k^2 = 0
            kmax = sqrt(ei/(-3.0_dp*c))
            mmax = ei*kmax + c*kmax**3
            if (abs(moment) >= mmax) then
                ok = .false.
                return
            end if
        end if
        do it = 1, 100
            f = ei*k + c*k**3 - moment
            d = tangent_stiffness(ei, c, k)
            if (d <= 0.0_dp) exit
            k = k - f/d
            if (abs(f) <= 4.0_dp*epsilon(1.0_dp)*max(abs(moment), ei*abs(k))) return
        end do
        f = ei*k + c*k**3 - moment
        ok = abs(f) <= 1.0e3_dp*epsilon(1.0_dp)*max(abs(moment), ei*abs(k), tiny(1.0_dp))
    end subroutine curvature_from_moment

    !> Shear and axial force across a joint kink of angle delta: the solution
    !! of dQ/dtheta = -a N, dN/dtheta = Q over theta in [0, delta], with its
    !! transfer matrix tq = d(Q+, N+)/d(Q-, N-) and the derivatives with
    !! respect to delta and a. With w = sqrt(a): Q+ = c Q - a S N,
    !! N+ = c N + S Q, c = cos(w delta), S = sin(w delta)/w.
    pure subroutine kink_transfer(a, delta, q, n, qplus, nplus, tq, dq_ddelta, dn_ddelta, &
                                  dq_da, dn_da)
        real(dp), intent(in) :: a, delta, q, n
        real(dp), intent(out) :: qplus, nplus, tq(2, 2), dq_ddelta, dn_ddelta, dq_da, dn_da
        real(dp) :: w, c, sinc, dc_da, ds_da, x
        x = a*delta*delta
        if (abs(x) < 1.0e-3_dp) then
            ! series in a delta^2 (exact at a = 0: c = 1, S = delta)
            c = 1.0_dp - x/2.0_dp + x*x/24.0_dp - x**3/720.0_dp
            sinc = delta*(1.0_dp - x/6.0_dp + x*x/120.0_dp - x**3/5040.0_dp)
            dc_da = -delta**2*(0.5_dp - x/12.0_dp + x*x/240.0_dp)
            ds_da = -delta**3*(1.0_dp/6.0_dp - x/60.0_dp + x*x/1680.0_dp)
        else
            w = sqrt(a)
            c = cos(w*delta)
            sinc = sin(w*delta)/w
            dc_da = -sinc*delta/2.0_dp
            ds_da = (c*delta - sinc)/(2.0_dp*a)
        end if
        qplus = c*q - a*sinc*n
        nplus = c*n + sinc*q
        tq = reshape([c, sinc, -a*sinc, c], [2, 2])
        dq_ddelta = -a*sinc*q - a*c*n
        dn_ddelta = -a*sinc*n + c*q
        dq_da = dc_da*q - sinc*n - a*ds_da*n
        dn_da = dc_da*n + ds_da*q
    end subroutine kink_transfer

    ! ---------------------------------------------------------- right-hand sides

    !> dz/ds of the equilibrium equations (module header).
    pure function rhs(z, ei, c, a) result(dz)
        real(dp), intent(in) :: z(NZ), ei, c, a
        real(dp) :: dz(NZ)
        dz(IX) = cos(z(IPSI))
        dz(IY) = sin(z(IPSI))
        dz(IPSI) = z(IK)
        dz(IK) = -z(IQ)/tangent_stiffness(ei, c, z(IK))
        dz(IQ) = -a*z(IK)*z(IN)
        dz(IN) = z(IK)*z(IQ)
    end function rhs

    !> d/ds of the variational columns: dv = (df/dz) V + df/dp (Eq. 33, 41).
    !! `dz` = rhs(z) supplies sin and cos of psi. Rows r0..NZ of dv are set;
    !! no row depends on the x and y rows of v, so r0 = IPSI skips them.
    pure subroutine rhs_var(z, dz, r0, ncol, v, colkind, ei, c, a, dv)
        real(dp), intent(in) :: z(NZ), dz(NZ), ei, c, a
        integer, intent(in) :: r0, ncol
        real(dp), intent(in) :: v(NZ, ncol)
        integer, intent(in) :: colkind(ncol)
        real(dp), intent(out) :: dv(NZ, ncol)
        real(dp) :: d, s, co, dkk, dkq, fei, fc, fa
        integer :: j
        d = tangent_stiffness(ei, c, z(IK))
        s = dz(IY)   ! sin(psi), already evaluated in rhs
        co = dz(IX)  ! cos(psi)
        dkk = 6.0_dp*c*z(IK)*z(IQ)/(d*d)
        dkq = -1.0_dp/d
        fei = z(IQ)/(d*d)
        fc = 3.0_dp*z(IK)**2*z(IQ)/(d*d)
        fa = -z(IK)*z(IN)
        if (r0 == IX) then
            do j = 1, ncol
                dv(IX, j) = -s*v(IPSI, j)
                dv(IY, j) = co*v(IPSI, j)
            end do
        end if
        do j = 1, ncol
            dv(IPSI, j) = v(IK, j)
            dv(IK, j) = dkk*v(IK, j) + dkq*v(IQ, j)
            dv(IQ, j) = -a*(z(IN)*v(IK, j) + z(IK)*v(IN, j))
            dv(IN, j) = z(IQ)*v(IK, j) + z(IK)*v(IQ, j)
            select case (colkind(j))
            case (COL_EI)
                dv(IK, j) = dv(IK, j) + fei
            case (COL_C)
                dv(IK, j) = dv(IK, j) + fc
            case (COL_A)
                dv(IQ, j) = dv(IQ, j) + fa
            end select
        end do
    end subroutine rhs_var

    ! -------------------------------------------------------------- integration

    !> One Dormand-Prince 5(4) step of length h from z (slope k1): the stage
    !! states z2..z6, the fifth-order result znew, the stage slopes k2..k7
    !! (k7 at znew, the next step's k1) and the error estimate zerr.
    pure subroutine dp_stages(z, k1, h, ei, c, a, z2, z3, z4, z5, z6, znew, k2, k3, k4, k5, &
                              k6, k7, zerr)
        real(dp), intent(in) :: z(NZ), k1(NZ), h, ei, c, a
        real(dp), intent(out), dimension(NZ) :: z2, z3, z4, z5, z6, znew, k2, k3, k4, k5, k6, &
                                                 k7, zerr
        z2 = z + h*a21*k1
        k2 = rhs(z2, ei, c, a)
        z3 = z + h*(a31*k1 + a32*k2)
        k3 = rhs(z3, ei, c, a)
        z4 = z + h*(a41*k1 + a42*k2 + a43*k3)
        k4 = rhs(z4, ei, c, a)
        z5 = z + h*(a51*k1 + a52*k2 + a53*k3 + a54*k4)
        k5 = rhs(z5, ei, c, a)
        z6 = z + h*(a61*k1 + a62*k2 + a63*k3 + a64*k4 + a65*k5)
        k6 = rhs(z6, ei, c, a)
        znew = z + h*(b1*k1 + b3*k3 + b4*k4 + b5*k5 + b6*k6)
        k7 = rhs(znew, ei, c, a)
        zerr = h*(e1*k1 + e3*k3 + e4*k4 + e5*k5 + e6*k6 + e7*k7)
    end subroutine dp_stages

    !> Advance the variational columns v (rows r0..NZ) over an accepted step
    !! with the stages of dp_stages; w holds the stage slopes (written whole
    !! by rhs_var), vs the stage arguments.
    pure subroutine advance_columns(z, z2, z3, z4, z5, z6, k1, k2, k3, k4, k5, k6, h, r0, ncol, &
                                    colkind, ei, c, a, v, w, vs)
        real(dp), intent(in), dimension(NZ) :: z, z2, z3, z4, z5, z6, k1, k2, k3, k4, k5, k6
        real(dp), intent(in) :: h, ei, c, a
        integer, intent(in) :: r0, ncol, colkind(:)
        real(dp), intent(inout), contiguous :: v(:, :), w(:, :, :), vs(:, :)
        associate (w1 => w(r0:, :, 1), w2 => w(r0:, :, 2), w3 => w(r0:, :, 3), &
                   w4 => w(r0:, :, 4), w5 => w(r0:, :, 5), w6 => w(r0:, :, 6), &
                   vr => v(r0:, :), vsr => vs(r0:, :))
        call rhs_var(z, k1, r0, ncol, v, colkind, ei, c, a, w(:, :, 1))
        vsr = vr + (h*a21)*w1
        call rhs_var(z2, k2, r0, ncol, vs, colkind, ei, c, a, w(:, :, 2))
        vsr = vr + h*(a31*w1 + a32*w2)
        call rhs_var(z3, k3, r0, ncol, vs, colkind, ei, c, a, w(:, :, 3))
        vsr = vr + h*(a41*w1 + a42*w2 + a43*w3)
        call rhs_var(z4, k4, r0, ncol, vs, colkind, ei, c, a, w(:, :, 4))
        vsr = vr + h*(a51*w1 + a52*w2 + a53*w3 + a54*w4)
        call rhs_var(z5, k5, r0, ncol, vs, colkind, ei, c, a, w(:, :, 5))
        vsr = vr + h*(a61*w1 + a62*w2 + a63*w3 + a64*w4 + a65*w5)
        call rhs_var(z6, k6, r0, ncol, vs, colkind, ei, c, a, w(:, :, 6))
        vr = vr + h*(b1*w1 + b3*w3 + b4*w4 + b5*w5 + b6*w6)
        end associate
    end subroutine advance_columns

    !> Integrate one beam from s = 0 to s = length with Dormand-Prince 5(4).
    !! Stations (local arc positions, ascending, in (0, length]) are landed on
    !! and their states stored.
    !! `w` and `vs` are work space for the stages of the columns v; rows
    !! before r0 of v are left as they are.
    subroutine integrate_beam(prob, beam, z, r0, v, colkind, stations, z_station, &
                              opts, steps, w, vs, stat, v_station)
        type(problem_t), intent(in) :: prob
        integer, intent(in) :: beam
        real(dp), intent(inout) :: z(NZ)
        integer, intent(in) :: r0   !< first row of v integrated: IX, or IPSI to skip x, y
        real(dp), intent(inout), contiguous :: v(:, :)
        real(dp), intent(inout), contiguous :: w(:, :, :), vs(:, :)
        integer, intent(in) :: colkind(:)
        real(dp), intent(in) :: stations(:)
        real(dp), intent(inout) :: z_station(:, :)
        type(static_options_t), intent(in) :: opts
        integer, intent(inout) :: steps
        type(status_t), intent(inout) :: stat
        !> the variational columns at the stations (NZ x ncol x stations)
        real(dp), intent(inout), optional :: v_station(:, :, :)

        real(dp) :: ei, c, a, length, s, h, hnew, err, sc(NZ)
        real(dp) :: k1(NZ), k2(NZ), k3(NZ), k4(NZ), k5(NZ), k6(NZ), k7(NZ)
        real(dp) :: z2(NZ), z3(NZ), z4(NZ), z5(NZ), z6(NZ), znew(NZ), zerr(NZ)
        integer :: ncol, next_station, nreject
        logical :: last, land, softening_lost

        ei = prob%chain%ei(beam)
        c = prob%chain%cubic(beam)
        a = prob%chain%axial_coupling
        length = prob%chain%length(beam)
        ncol = size(v, 2)
        ! error weights: lengths scale with the arm, forces with EI/L^2
        sc = [prob%total_length, prob%total_length, 1.0_dp, 1.0_dp/prob%total_length, &
              prob%force_scale, prob%force_scale]

        s = 0.0_dp
        ! first try: an eighth of the beam at tol 1e-9, scaled like the step of a
        ! fifth-order method, tol^(1/5), for the loose Newton shots
        h = min(length, length/8.0_dp*(opts%tol/1.0e-9_dp)**0.2_dp)
        next_station = 1
        nreject = 0
        k1 = rhs(z, ei, c, a)
        do
            land = .false.
            last = .false.
            if (next_station <= size(stations)) then
                if (s + h >= stations(next_station) - 1.0e-14_dp*length) then
                    h = stations(next_station) - s
                    land = .true.
                end if
            end if
            if (s + h >= length - 1.0e-14_dp*length) then
                h = length - s
                last = .true.
            end if
            if (steps >= opts%max_rk_steps) then
                call set_status(stat, ERR_NUMERIC, 'arc-length integration', &
                                'more than '//fmt_int(opts%max_rk_steps)//' steps on beam '// &
                                fmt_int(beam)//' at s = '//fmt_real(s)// &
                                ' (curvature '//fmt_real(z(IK))//'): step size collapsed')
                return
            end if
            call dp_stages(z, k1, h, ei, c, a, z2, z3, z4, z5, z6, znew, k2, k3, k4, k5, k6, k7, &
                           zerr)
            err = maxval(abs(zerr)/(opts%tol*(sc + max(abs(z), abs(znew)))))
            steps = steps + 1
            ! a softening law (C < 0) must stay on its branch: EI + 3 C k^2 > 0
            softening_lost = .false.
            if (c < 0.0_dp) softening_lost = .not. stage_ok()
            if (.not. (err <= 1.0_dp) .or. softening_lost) then
                ! reject (also on NaN: the comparison above is false for NaN)
                nreject = nreject + 1
                if (.not. (err == err) .or. softening_lost) then
                    h = 0.25_dp*h
                else
                    h = h*max(0.2_dp, 0.9_dp*err**(-0.2_dp))
                end if
                if (h < 1.0e-12_dp*length) then
                    call set_status(stat, ERR_NUMERIC, 'arc-length integration', &
                                    'step size underflow on beam '//fmt_int(beam)// &
                                    ' at s = '//fmt_real(s)//' (curvature '// &
                                    fmt_real(z(IK))//'; a softening C past its limit?)')
                    return
                end if
                cycle
            end if
            ! accepted: advance the variational columns with the same stages
            if (ncol > 0) call advance_columns(z, z2, z3, z4, z5, z6, k1, k2, k3, k4, k5, k6, &
                                               h, r0, ncol, colkind, ei, c, a, v, w, vs)
            z = znew
            k1 = k7
            hnew = h*min(5.0_dp, max(0.2_dp, 0.9_dp*max(err, 1.0e-10_dp)**(-0.2_dp)))
            if (last) then
                s = length
            else
                s = s + h
            end if
            if (land .or. last) then
                do while (next_station <= size(stations))
                    if (stations(next_station) > s + 1.0e-14_dp*length) exit
                    z_station(:, next_station) = z
                    if (present(v_station)) v_station(:, :, next_station) = v
                    next_station = next_station + 1
                end do
            end if
            if (last) exit
            if (.not. land) h = hnew
            if (land) h = max(h, hnew)
        end do
        do while (next_station <= size(stations))
            z_station(:, next_station) = z
            if (present(v_station)) v_station(:, :, next_station) = v
            next_station = next_station + 1
        end do

    contains

        logical function stage_ok()
            stage_ok = all([tangent_stiffness(ei, c, z2(IK)), tangent_stiffness(ei, c, z3(IK)), &
                            tangent_stiffness(ei, c, z4(IK)), tangent_stiffness(ei, c, z5(IK)), &
                            tangent_stiffness(ei, c, z6(IK)), tangent_stiffness(ei, c, znew(IK))] &
                           > 0.0_dp)
        end function stage_ok
    end subroutine integrate_beam

    !> Give the arrays of a shot the shapes for ncol columns on nb beams,
    !! reallocating only what changed.
    pure subroutine size_shot(shot, ncol, nb)
        type(shot_t), intent(inout) :: shot
        integer, intent(in) :: ncol, nb
        if (allocated(shot%v_end)) then
            if (size(shot%v_end, 2) /= ncol .or. size(shot%z_joint, 2) /= nb) &
                deallocate (shot%v_end, shot%z_joint, shot%v_joint)
        end if
        if (.not. allocated(shot%v_end)) &
            allocate (shot%v_end(NZ, ncol), shot%z_joint(NZ, nb), shot%v_joint(NZ, ncol, nb))
        associate (wk => shot%work)
        if (allocated(wk%v)) then
            if (size(wk%v, 2) /= ncol) deallocate (wk%v, wk%w, wk%vs, wk%colkind, wk%vk_old, &
                                                   wk%ddelta, wk%vq_old, wk%vn_old)
        end if
        if (.not. allocated(wk%v)) &
            allocate (wk%v(NZ, ncol), wk%w(NZ, ncol, 6), wk%vs(NZ, ncol), wk%colkind(ncol), &
                      wk%vk_old(ncol), wk%ddelta(ncol), wk%vq_old(ncol), wk%vn_old(ncol))
        end associate
    end subroutine size_shot

    !> Integrate the whole chain from the root for given unknowns.
    !! Columns of the variational matrix: 1..NSHOOT are d/du (k0, Q0, N0),
    !! the rest d/dparams(wrt(j)). Stations are global arc positions.
    subroutine shoot(prob, u, wrt, with_u_cols, opts, shot, stat, stations, z_station)
        type(problem_t), intent(in) :: prob
        real(dp), intent(in) :: u(:)
        integer, intent(in) :: wrt(:)
        logical, intent(in) :: with_u_cols
        type(static_options_t), intent(in) :: opts
        type(shot_t), intent(inout) :: shot
        type(status_t), intent(inout) :: stat
        real(dp), intent(in), optional :: stations(:)
        real(dp), intent(inout), optional :: z_station(:, :)
        integer :: ncol, nu0, nb, i, r0
        real(dp) :: z(NZ), s0

        nb = prob%chain%nbeams
        nu0 = merge(NSHOOT, 0, with_u_cols)
        ncol = nu0 + size(wrt)
        ! the x, y rows of the columns feed nothing but the outputs' sensitivities
        ! and the wire's tip condition: a Newton shot of a tip load without
        ! sensitivities leaves them at zero
        r0 = IX
        if (size(wrt) == 0 .and. prob%load%kind == LOAD_TIP) r0 = IPSI
        call size_shot(shot, ncol, nb)
        shot%work%v = 0.0_dp
        shot%steps = 0
        call root_state(prob%chain, u, wrt, nu0, with_u_cols, z, shot%work%v)
        s0 = 0.0_dp
        do i = 1, nb
            call column_kinds(nb, i, wrt, nu0, shot%work%colkind)
            call integrate_beam_stations(prob, i, s0, r0, opts, z, shot, stat, stations, &
                                         z_station)
            if (stat%code /= STATUS_OK) return
            s0 = s0 + prob%chain%length(i)
            call add_length_columns(prob%chain, i, wrt, nu0, z, shot%work%v)
            shot%z_joint(:, i) = z
            shot%v_joint(:, :, i) = shot%work%v
            if (i == nb) exit
            call cross_joint(prob%chain, i, wrt, nu0, z, shot%work, stat)
            if (stat%code /= STATUS_OK) return
        end do
        shot%z_end = z
        shot%v_end = shot%work%v
    end subroutine shoot

    !> Root state z(0) and columns v(0): psi(0) = f_root M(0),
    !! M(0) = EI1 k0 + C1 k0^3, (k, Q, N)(0) = u.
    pure subroutine root_state(ch, u, wrt, nu0, with_u_cols, z, v)
        type(chain_t), intent(in) :: ch
        real(dp), intent(in) :: u(:)
        integer, intent(in) :: wrt(:), nu0
        logical, intent(in) :: with_u_cols
        real(dp), intent(out) :: z(NZ)
        real(dp), intent(inout) :: v(:, :)
        real(dp) :: k0, m0, d0
        integer :: j, p, nb
        nb = ch%nbeams
        k0 = u(1)
        m0 = ch%ei(1)*k0 + ch%cubic(1)*k0**3
        d0 = tangent_stiffness(ch%ei(1), ch%cubic(1), k0)
        z = [0.0_dp, 0.0_dp, ch%root_flex*m0, k0, u(2), u(3)]
        if (with_u_cols) then
            v(IPSI, 1) = ch%root_flex*d0
            v(IK, 1) = 1.0_dp
            v(IQ, 2) = 1.0_dp
            v(IN, 3) = 1.0_dp
        end if
        do j = 1, size(wrt)
            p = wrt(j)
            if (p == param_index_global(nb, IG_ROOT_FLEX)) v(IPSI, nu0 + j) = m0
            if (p == param_index_beam(nb, 1, IB_EI)) v(IPSI, nu0 + j) = ch%root_flex*k0
            if (p == param_index_beam(nb, 1, IB_C)) v(IPSI, nu0 + j) = ch%root_flex*k0**3
        end do
    end subroutine root_state

    !> How each column is forced on beam i (COL_*).
    pure subroutine column_kinds(nb, i, wrt, nu0, colkind)
        integer, intent(in) :: nb, i, wrt(:), nu0
        integer, intent(out) :: colkind(:)
        integer :: j, p
        colkind = COL_FREE
        do j = 1, size(wrt)
            p = wrt(j)
            if (p == param_index_beam(nb, i, IB_EI)) colkind(nu0 + j) = COL_EI
            if (p == param_index_beam(nb, i, IB_C)) colkind(nu0 + j) = COL_C
            if (p == param_index_global(nb, IG_AXIAL_COUPLING)) colkind(nu0 + j) = COL_A
        end do
    end subroutine column_kinds

    !> Integrate beam i (starting at arc position s0) and record the state at
    !! the stations that fall on it.
    subroutine integrate_beam_stations(prob, i, s0, r0, opts, z, shot, stat, stations, &
                                       z_station)
        type(problem_t), intent(in) :: prob
        integer, intent(in) :: i, r0
        real(dp), intent(in) :: s0
        type(static_options_t), intent(in) :: opts
        real(dp), intent(inout) :: z(NZ)
        type(shot_t), intent(inout) :: shot
        type(status_t), intent(inout) :: stat
        real(dp), intent(in), optional :: stations(:)
        real(dp), intent(inout), optional :: z_station(:, :)
        real(dp) :: no_local(0), no_zst(NZ, 0)
        real(dp), allocatable :: local(:), zst(:, :)
        integer :: j, nst, first, last
        associate (ch => prob%chain, wk => shot%work)
        first = 1
        last = 0
        if (present(stations)) then
            nst = size(stations)
            first = findloc(stations > s0 .or. (i == 1 .and. stations >= s0), .true., 1)
            if (first == 0) first = nst + 1
            last = first - 1
            do j = first, nst
                if (stations(j) <= s0 + ch%length(i) .or. i == ch%nbeams) last = j
            end do
            ! stations at the root itself are recorded before integrating
            do while (first <= last)
                if (stations(first) > s0) exit
                z_station(:, first) = z
                first = first + 1
            end do
        end if
        if (last >= first) then
            allocate (local(last - first + 1), zst(NZ, last - first + 1))
            local = min(stations(first:last) - s0, ch%length(i))
            call integrate_beam(prob, i, z, r0, wk%v, wk%colkind, local, zst, opts, shot%steps, &
                                wk%w, wk%vs, stat)
            if (stat%code == STATUS_OK) z_station(:, first:last) = zst
        else
            call integrate_beam(prob, i, z, r0, wk%v, wk%colkind, no_local, no_zst, opts, &
                                shot%steps, wk%w, wk%vs, stat)
        end if
        end associate
    end subroutine integrate_beam_stations

    !> d/dL_i: the end point of beam i moves along the solution.
    pure subroutine add_length_columns(ch, i, wrt, nu0, z, v)
        type(chain_t), intent(in) :: ch
        integer, intent(in) :: i, wrt(:), nu0
        real(dp), intent(in) :: z(NZ)
        real(dp), intent(inout) :: v(:, :)
        real(dp) :: fend(NZ)
        integer :: j
        fend = rhs(z, ch%ei(i), ch%cubic(i), ch%axial_coupling)
        do j = 1, size(wrt)
            if (wrt(j) == param_index_beam(ch%nbeams, i, IB_L)) v(:, nu0 + j) = v(:, nu0 + j) + fend
        end do
    end subroutine add_length_columns

    !> Across joint i: moment continuous (Eq. 20), optional kink psi+ = psi- + f M,
    !! for the state z and the columns wk%v.
    pure subroutine cross_joint(ch, i, wrt, nu0, z, wk, stat)
        type(chain_t), intent(in) :: ch
        integer, intent(in) :: i, wrt(:), nu0
        real(dp), intent(inout) :: z(NZ)
        type(shot_work_t), intent(inout) :: wk
        type(status_t), intent(inout) :: stat
        real(dp) :: kminus, kplus, mminus, dminus, dplus, flex
        real(dp) :: qplus, nplus, tq(2, 2), dq_ddelta, dn_ddelta, dq_da, dn_da
        integer :: j, p, nb
        logical :: ok
        nb = ch%nbeams
        associate (v => wk%v, vk_old => wk%vk_old, ddelta => wk%ddelta, vq_old => wk%vq_old, &
                   vn_old => wk%vn_old)
        kminus = z(IK)
        mminus = ch%ei(i)*kminus + ch%cubic(i)*kminus**3
        dminus = tangent_stiffness(ch%ei(i), ch%cubic(i), kminus)
        call curvature_from_moment(ch%ei(i + 1), ch%cubic(i + 1), mminus, kplus, ok)
        if (.not. ok) then
            call set_status(stat, ERR_NUMERIC, 'arc-length joint', 'joint '// &
                            fmt_int(i)//' moment '//fmt_real(mminus)// &
                            ' exceeds what the softening law of beam '//fmt_int(i + 1)// &
                            ' can carry (C'//fmt_int(i + 1)//' < 0)')
            return
        end if
        dplus = tangent_stiffness(ch%ei(i + 1), ch%cubic(i + 1), kplus)
        flex = ch%joint_flex(i)
        vk_old = v(IK, :)
        ! kink angle delta = f M- and its variation
        ddelta = flex*dminus*vk_old
        v(IK, :) = (dminus/dplus)*vk_old
        do j = 1, size(wrt)
            p = wrt(j)
            if (p == param_index_joint_flex(nb, i)) ddelta(nu0 + j) = ddelta(nu0 + j) + mminus
            if (p == param_index_beam(nb, i, IB_EI)) then
                ddelta(nu0 + j) = ddelta(nu0 + j) + flex*kminus
                v(IK, nu0 + j) = v(IK, nu0 + j) + kminus/dplus
            end if
            if (p == param_index_beam(nb, i, IB_C)) then
                ddelta(nu0 + j) = ddelta(nu0 + j) + flex*kminus**3
                v(IK, nu0 + j) = v(IK, nu0 + j) + kminus**3/dplus
            end if
            if (p == param_index_beam(nb, i + 1, IB_EI)) &
                v(IK, nu0 + j) = v(IK, nu0 + j) - kplus/dplus
            if (p == param_index_beam(nb, i + 1, IB_C)) &
                v(IK, nu0 + j) = v(IK, nu0 + j) - kplus**3/dplus
        end do
        v(IPSI, :) = v(IPSI, :) + ddelta
        ! (Q, N) across the kink: the limit of a concentrated curvature delta,
        ! i.e. Q' = -a k N, N' = k Q integrated over the angle delta (a = 1:
        ! the force components rotate into the new tangent frame).
        call kink_transfer(ch%axial_coupling, flex*mminus, z(IQ), z(IN), qplus, nplus, &
                           tq, dq_ddelta, dn_ddelta, dq_da, dn_da)
        vq_old = v(IQ, :)
        vn_old = v(IN, :)
        v(IQ, :) = tq(1, 1)*vq_old + tq(1, 2)*vn_old + dq_ddelta*ddelta
        v(IN, :) = tq(2, 1)*vq_old + tq(2, 2)*vn_old + dn_ddelta*ddelta
        do j = 1, size(wrt)
            if (wrt(j) == param_index_global(nb, IG_AXIAL_COUPLING)) then
                v(IQ, nu0 + j) = v(IQ, nu0 + j) + dq_da
                v(IN, nu0 + j) = v(IN, nu0 + j) + dn_da
            end if
        end do
        z(IQ) = qplus
        z(IN) = nplus
        z(IPSI) = z(IPSI) + flex*mminus
        z(IK) = kplus
        end associate
    end subroutine cross_joint

    ! ------------------------------------------------------------ tip conditions

    !> Tip force vector, including the wire's pull towards the root.
    pure subroutine tip_force(prob, z, tension, px, py)
        type(problem_t), intent(in) :: prob
        real(dp), intent(in) :: z(NZ), tension
        real(dp), intent(out) :: px, py
        real(dp) :: r
        if (prob%load%kind == LOAD_WIRE) then
            r = hypot(z(IX), z(IY))
            px = -tension*z(IX)/r
            py = -tension*z(IY)/r
        else
            px = prob%load_factor*prob%load%fx
            py = prob%load_factor*prob%load%fy
        end if
    end subroutine tip_force

    !> Scaled tip residuals g (Eq. 23, 27 corrected, 22) and their derivatives
    !! with respect to the tip state (dg_dz) and to the tension (dg_dt).
    pure subroutine tip_residual(prob, z, tension, g, dg_dz, dg_dt)
        type(problem_t), intent(in) :: prob
        real(dp), intent(in) :: z(NZ), tension
        real(dp), intent(out) :: g(:), dg_dz(:, :), dg_dt(:)
        real(dp) :: px, py, s, c, pn, pt, r, ei, cc, dpx(NZ), dpy(NZ), dpx_t, dpy_t
        integer :: nb
        nb = prob%chain%nbeams
        ei = prob%chain%ei(nb)
        cc = prob%chain%cubic(nb)
        call tip_force(prob, z, tension, px, py)
        s = sin(z(IPSI))
        c = cos(z(IPSI))
        pn = -px*s + py*c
        pt = px*c + py*s
        dpx = 0.0_dp
        dpy = 0.0_dp
        dpx_t = 0.0_dp
        dpy_t = 0.0_dp
        if (prob%load%kind == LOAD_WIRE) then
            r = hypot(z(IX), z(IY))
            dpx(IX) = -tension*(1.0_dp/r - z(IX)**2/r**3)
            dpx(IY) = tension*z(IX)*z(IY)/r**3
            dpy(IX) = tension*z(IX)*z(IY)/r**3
            dpy(IY) = -tension*(1.0_dp/r - z(IY)**2/r**3)
            dpx_t = -z(IX)/r
            dpy_t = -z(IY)/r
        end if
        g = 0.0_dp
        dg_dz = 0.0_dp
        dg_dt = 0.0_dp
        ! moment at the tip equals the applied moment (zero: Eq. 23)
        g(1) = (ei*z(IK) + cc*z(IK)**3 - prob%load_factor*prob%load%moment)/prob%moment_scale
        dg_dz(1, IK) = tangent_stiffness(ei, cc, z(IK))/prob%moment_scale
        ! shear equals the normal component of the tip force
        g(2) = (z(IQ) - pn)/prob%force_scale
        dg_dz(2, IQ) = 1.0_dp/prob%force_scale
        dg_dz(2, IPSI) = pt/prob%force_scale
        dg_dz(2, :) = dg_dz(2, :) - (-s*dpx + c*dpy)/prob%force_scale
        dg_dt(2) = -(-s*dpx_t + c*dpy_t)/prob%force_scale
        ! axial force equals the tangential component
        g(3) = (z(IN) - pt)/prob%force_scale
        dg_dz(3, IN) = 1.0_dp/prob%force_scale
        dg_dz(3, IPSI) = -pn/prob%force_scale
        dg_dz(3, :) = dg_dz(3, :) - (c*dpx + s*dpy)/prob%force_scale
        dg_dt(3) = -(c*dpx_t + s*dpy_t)/prob%force_scale
        if (prob%load%kind == LOAD_WIRE) then
            ! the tip lies on the circle of the wire (Eq. 22a)
            g(4) = (r - prob%load%wire_length)/prob%total_length
            dg_dz(4, IX) = z(IX)/(r*prob%total_length)
            dg_dz(4, IY) = z(IY)/(r*prob%total_length)
        end if
    end subroutine tip_residual

    !> Residual and Newton matrix at unknowns u; the shot carries the
    !! variational columns for params(wrt) as well.
    subroutine evaluate(prob, u, wrt, opts, g, jac, shot, stat)
        type(problem_t), intent(in) :: prob
        real(dp), intent(in) :: u(:)
        integer, intent(in) :: wrt(:)
        type(static_options_t), intent(in) :: opts
        real(dp), intent(out) :: g(:), jac(:, :)
        type(shot_t), intent(inout) :: shot
        type(status_t), intent(inout) :: stat
        real(dp) :: dg_dz(prob%nu, NZ), dg_dt(prob%nu), tension
        tension = 0.0_dp
        if (prob%nu == 4) tension = u(4)
        call shoot(prob, u, wrt, .true., opts, shot, stat)
        if (stat%code /= STATUS_OK) return
        call tip_residual(prob, shot%z_end, tension, g, dg_dz, dg_dt)
        jac = 0.0_dp
        jac(:, 1:NSHOOT) = matmul(dg_dz, shot%v_end(:, 1:NSHOOT))
        if (prob%nu == 4) jac(:, 4) = dg_dt
    end subroutine evaluate

    !> Hand the results of one shot to another without copying: the arrays are
    !! swapped, so `from` keeps storage to be reused by the next trial shot.
    pure subroutine move_shot(from, to)
        type(shot_t), intent(inout) :: from, to
        real(dp), allocatable :: tmp2(:, :), tmp3(:, :, :)
        to%z_end = from%z_end
        to%steps = from%steps
        call move_alloc(to%v_end, tmp2)
        call move_alloc(from%v_end, to%v_end)
        call move_alloc(tmp2, from%v_end)
        call move_alloc(to%z_joint, tmp2)
        call move_alloc(from%z_joint, to%z_joint)
        call move_alloc(tmp2, from%z_joint)
        call move_alloc(to%v_joint, tmp3)
        call move_alloc(from%v_joint, to%v_joint)
        call move_alloc(tmp3, from%v_joint)
    end subroutine move_shot

    !> Damped Newton on the tip conditions from the guess in u.
    !! Inexact Newton: while the residual r is large the shots are integrated
    !! to a looser tolerance (1e-3 r^2 capped at LOOSE_TOL_MAX, never tighter
    !! than needed for quadratic convergence) and without the sensitivity
    !! columns; the shot that declares convergence is always at opts%tol and
    !! carries the columns for wrt, so `shot` returns the integration at the
    !! final u.
    subroutine newton(prob, u, wrt, opts, iterations, resid, shot, stat)
        type(problem_t), intent(in) :: prob
        real(dp), intent(inout) :: u(:)
        integer, intent(in) :: wrt(:)
        type(static_options_t), intent(in) :: opts
        integer, intent(out) :: iterations
        real(dp), intent(out) :: resid
        type(shot_t), intent(inout) :: shot
        type(status_t), intent(inout) :: stat
        type(shot_t) :: shot_try
        type(static_options_t) :: work
        real(dp) :: g(prob%nu), jac(prob%nu, prob%nu), step(prob%nu, 1), utry(prob%nu)
        real(dp) :: gtry(prob%nu), jtry(prob%nu, prob%nu), alpha, rtry, tol_now, tol_try
        real(dp) :: newton_tol
        type(status_t) :: trial
        integer :: it, ls
        integer :: no_wrt(0)

        iterations = 0
        work = opts
        if (.not. (work%newton_tol > 0.0_dp)) work%newton_tol = 10.0_dp*opts%tol
        newton_tol = work%newton_tol
        tol_now = max(opts%tol, LOOSE_TOL_MAX)
        work%tol = tol_now
        if (tol_now > opts%tol) then
            call evaluate(prob, u, no_wrt, work, g, jac, shot, stat)
        else
            call evaluate(prob, u, wrt, work, g, jac, shot, stat)
        end if
        if (stat%code /= STATUS_OK) then
            resid = huge(1.0_dp)
            return
        end if
        resid = maxval(abs(g))
        do it = 1, opts%max_newton
            if (resid <= newton_tol) then
                if (tol_now <= opts%tol) return
                ! converged on a loose shot: redo this point at the requested accuracy
                tol_now = opts%tol
                work%tol = tol_now
                call evaluate(prob, u, wrt, work, g, jac, shot, stat)
                if (stat%code /= STATUS_OK) return
                resid = maxval(abs(g))
                if (resid <= newton_tol) return
            end if
            iterations = it
            step(:, 1) = -g
            call solve_dense(jac, step, stat)
            if (stat%code /= STATUS_OK) return
            tol_try = max(opts%tol, min(LOOSE_TOL_MAX, 1.0e-3_dp*resid*resid))
            work%tol = tol_try
            alpha = 1.0_dp
            do ls = 1, 12
                utry = u + alpha*step(:, 1)
                trial%code = STATUS_OK
                if (tol_try > opts%tol) then
                    call evaluate(prob, utry, no_wrt, work, gtry, jtry, shot_try, trial)
                else
                    call evaluate(prob, utry, wrt, work, gtry, jtry, shot_try, trial)
                end if
                if (trial%code == STATUS_OK) then
                    rtry = maxval(abs(gtry))
                    if (rtry < (1.0_dp - 1.0e-4_dp*alpha)*resid .or. rtry <= newton_tol) exit
                end if
                alpha = 0.5_dp*alpha
            end do
            if ((trial%code /= STATUS_OK .or. ls > 12) .and. tol_now > opts%tol) then
                ! the residual of a loose shot may be below what the step can reach:
                ! re-evaluate this point at the requested accuracy and go on
                tol_now = opts%tol
                work%tol = tol_now
                call evaluate(prob, u, wrt, work, g, jac, shot, stat)
                if (stat%code /= STATUS_OK) return
                resid = maxval(abs(g))
                cycle
            end if
            if (trial%code /= STATUS_OK .or. ls > 12) then
                call set_status(stat, ERR_NO_CONVERGENCE, 'static Newton', &
                                'line search failed after '//fmt_int(it)// &
                                ' iterations, scaled residual '//fmt_real(resid))
                return
            end if
            u = utry
            g = gtry
            jac = jtry
            resid = rtry
            tol_now = tol_try
            call move_shot(shot_try, shot)
        end do
        if (resid > newton_tol .or. tol_now > opts%tol) call set_status(stat, &
                ERR_NO_CONVERGENCE, 'static Newton', 'no convergence in '// &
                fmt_int(opts%max_newton)//' iterations, scaled residual '//fmt_real(resid)// &
                ' > '//fmt_real(newton_tol))
    end subroutine newton

    ! --------------------------------------------------------------- public API

    !> Load case from plain values (the f2py binding's): kind LOAD_TIP or
    !! LOAD_WIRE and values (fx, fy, moment, wire_length).
    pure function static_load_from_values(kind, values) result(load)
        integer, intent(in) :: kind
        real(dp), intent(in) :: values(4)
        type(static_load_t) :: load
        load = static_load_t(kind, values(1), values(2), values(3), values(4))
    end function static_load_from_values

    !> Default options with the integration tolerance tol (tol <= 0: default).
    pure function static_options_from_tol(tol) result(opts)
        real(dp), intent(in) :: tol
        type(static_options_t) :: opts
        if (tol > 0.0_dp) opts%tol = tol
    end function static_options_from_tol

    !> Check a load case against a chain; empty status when fine.
    pure subroutine validate_static_load(chain, load, stat)
        type(chain_t), intent(in) :: chain
        type(static_load_t), intent(in) :: load
        type(status_t), intent(inout) :: stat
        real(dp) :: total
        total = sum(chain%length)
        select case (load%kind)
        case (LOAD_TIP)
            if (.not. all(ieee_is_finite([load%fx, load%fy, load%moment]))) then
                call set_status(stat, ERR_INPUT, 'load', 'tip load (fx, fy, moment) = ('// &
                                fmt_real(load%fx)//', '//fmt_real(load%fy)//', '// &
                                fmt_real(load%moment)//'), expected finite numbers')
            end if
        case (LOAD_WIRE)
            if (.not. ieee_is_finite(load%wire_length) .or. load%wire_length <= 0.0_dp) then
                call set_status(stat, ERR_INPUT, 'load', 'wire length Lw = '// &
                                fmt_real(load%wire_length)//', expected a positive length')
            else if (load%wire_length >= total) then
                call set_status(stat, ERR_INPUT, 'load', 'wire length Lw = '// &
                                fmt_real(load%wire_length)//' is not shorter than the arm ('// &
                                fmt_real(total)//' m): the wire would be slack')
            else if (load%wire_length < 0.05_dp*total) then
                call set_status(stat, ERR_INPUT, 'load', 'wire length Lw = '// &
                                fmt_real(load%wire_length)//' is too short to reach: '// &
                                'expected at least 5 % of the arm length ('// &
                                fmt_real(0.05_dp*total)//' m)')
            end if
        case default
            call set_status(stat, ERR_INPUT, 'load', 'load kind '//fmt_int(load%kind)// &
                            ', expected 1 (tip force/moment) or 2 (radial wire)')
        end select
    end subroutine validate_static_load

    !> A short description of a load for messages.
    pure function load_text(load) result(text)
        type(static_load_t), intent(in) :: load
        character(len=:), allocatable :: text
        if (load%kind == LOAD_WIRE) then
            text = 'radial wire Lw = '//fmt_real(load%wire_length)
        else
            text = 'tip force ('//fmt_real(load%fx)//', '//fmt_real(load%fy)// &
                   ') N, tip moment '//fmt_real(load%moment)//' N m'
        end if
    end function load_text

    subroutine setup_problem(chain, load, prob)
        type(chain_t), intent(in) :: chain
        type(static_load_t), intent(in) :: load
        type(problem_t), intent(out) :: prob
        prob%chain = chain
        prob%load = load
        prob%total_length = sum(chain%length)
        ! residuals and error weights are measured against the applied load, so
        ! that small loads are solved to the same relative accuracy as large ones
        prob%force_scale = chain%ei(1)/prob%total_length**2
        if (load%kind == LOAD_TIP) prob%force_scale = max(hypot(load%fx, load%fy), &
            abs(load%moment)/prob%total_length, 1.0e-12_dp*prob%force_scale)
        prob%moment_scale = prob%force_scale*prob%total_length
        prob%nu = merge(4, 3, load%kind == LOAD_WIRE)
    end subroutine setup_problem

    !> Solve the static problem and the sensitivities of all outputs with
    !! respect to params(wrt(:)) (indices in the layout of beamid_model).
    subroutine solve_static(chain, load, wrt, opts, sol, stat)
        type(chain_t), intent(in) :: chain
        type(static_load_t), intent(in) :: load
        integer, intent(in) :: wrt(:)
        type(static_options_t), intent(in) :: opts
        type(static_solution_t), intent(out) :: sol
        type(status_t), intent(inout) :: stat
        type(problem_t) :: prob
        type(shot_t) :: shot
        real(dp), allocatable :: u(:)
        integer :: j

        call validate_static_load(chain, load, stat)
        if (stat%code /= STATUS_OK) return
        do j = 1, size(wrt)
            if (wrt(j) < 1 .or. wrt(j) > param_count(chain%nbeams)) then
                call set_status(stat, ERR_INPUT, 'solve_static', 'sensitivity index '// &
                                fmt_int(wrt(j))//' out of range 1..'// &
                                fmt_int(param_count(chain%nbeams)))
                return
            end if
        end do
        call setup_problem(chain, load, prob)
        allocate (u(prob%nu))
        if (load%kind == LOAD_WIRE) then
            call solve_wire(prob, wrt, opts, u, shot, sol, stat)
        else
            call solve_tip(prob, wrt, opts, u, shot, sol, stat)
        end if
        if (stat%code /= STATUS_OK) then
            ! every failure names the load it failed on
            if (index(stat%message, 'Lw =') == 0 .and. index(stat%message, 'tip force') == 0) &
                stat%message = trim(stat%message)//' ('//load_text(load)//')'
            return
        end if
        ! (nested: Fortran's .and. does not short-circuit, and u has no 4th
        ! entry for a tip load)
        if (load%kind == LOAD_WIRE) then
            if (.not. (u(4) > 0.0_dp)) then
                call set_status(stat, ERR_NO_CONVERGENCE, 'radial wire', 'the only '// &
                                'equilibrium found for Lw = '//fmt_real(load%wire_length)// &
                                ' pushes on the tip (tension '//fmt_real(u(4))// &
                                ' N): no taut-wire shape found')
                return
            end if
        end if
        ! after continuation the last shot may lack the sensitivity columns
        if (size(shot%v_end, 2) /= NSHOOT + size(wrt)) then
            call shoot(prob, u, wrt, .true., opts, shot, stat)
            if (stat%code /= STATUS_OK) return
        end if
        call finish(prob, u, wrt, shot, sol, stat)
    end subroutine solve_static

    !> Tip force and moment: Newton from the linear guess, else continuation
    !! in the load factor from the unloaded straight arm.
    subroutine solve_tip(prob, wrt, opts, u, shot, sol, stat)
        type(problem_t), intent(inout) :: prob
        integer, intent(in) :: wrt(:)
        type(static_options_t), intent(in) :: opts
        real(dp), intent(inout) :: u(:)
        type(shot_t), intent(inout) :: shot
        type(static_solution_t), intent(inout) :: sol
        type(status_t), intent(inout) :: stat
        type(status_t) :: first_try
        real(dp) :: m0
        logical :: ok
        integer :: its

        m0 = prob%load%moment + prob%load%fy*prob%total_length
        call curvature_from_moment(prob%chain%ei(1), prob%chain%cubic(1), m0, u(1), ok)
        if (.not. ok) u(1) = m0/prob%chain%ei(1)
        u(2) = prob%load%fy
        u(3) = prob%load%fx
        prob%load_factor = 1.0_dp
        call newton(prob, u, wrt, opts, its, sol%residual, shot, first_try)
        sol%newton_iterations = its
        sol%load_steps = 1
        if (first_try%code == STATUS_OK) return
        u = 0.0_dp
        call continuation(prob, opts, u, 0.0_dp, 1.0_dp, .false., shot, sol, stat)
    end subroutine solve_tip

    !> Radial wire: the shear-only form reduces to one unknown (the constant
    !! shear), found by bracketing; then Newton on the full system, then
    !! continuation in axial_coupling up to the requested value.
    subroutine solve_wire(prob, wrt, opts, u, shot_out, sol, stat)
        type(problem_t), intent(inout) :: prob
        integer, intent(in) :: wrt(:)
        type(static_options_t), intent(in) :: opts
        real(dp), intent(inout) :: u(:)
        type(shot_t), intent(inout) :: shot_out
        type(static_solution_t), intent(inout) :: sol
        type(status_t), intent(inout) :: stat
        real(dp) :: target_a, qlo, qhi, rlo, rhi, q, r, tnorm, nrm
        type(shot_t) :: shot
        integer :: it, its
        integer :: no_wrt(0)
        logical :: ok

        target_a = prob%chain%axial_coupling
        prob%chain%axial_coupling = 0.0_dp
        ! bracket the constant shear Q0 that brings the tip to |r| = Lw
        qlo = 0.0_dp
        rlo = prob%total_length
        qhi = 0.25_dp*prob%force_scale
        do it = 1, 60
            call wire_radius(qhi, rhi, shot, ok)
            if (.not. ok) then
                call set_status(stat, ERR_NO_CONVERGENCE, 'radial wire', 'no shape '// &
                                'with tip radius Lw = '//fmt_real(prob%load%wire_length)// &
                                ' found before the material law failed')
                return
            end if
            if (rhi <= prob%load%wire_length) exit
            qlo = qhi
            rlo = rhi
            qhi = 2.0_dp*qhi
        end do
        if (rhi > prob%load%wire_length) then
            call set_status(stat, ERR_NO_CONVERGENCE, 'radial wire', 'could not bracket '// &
                            'the shear for Lw = '//fmt_real(prob%load%wire_length))
            return
        end if
        ! regula falsi (Illinois) on r(Q0) - Lw
        q = qhi
        do it = 1, 200
            q = qhi - (rhi - prob%load%wire_length)*(qhi - qlo)/(rhi - rlo)
            call wire_radius(q, r, shot, ok)
            if (.not. ok) exit
            if (abs(r - prob%load%wire_length) <= 1.0e-13_dp*prob%total_length) exit
            if ((r - prob%load%wire_length)*(rhi - prob%load%wire_length) < 0.0_dp) then
                qlo = qhi
                rlo = rhi
            else
                rlo = prob%load%wire_length + 0.5_dp*(rlo - prob%load%wire_length)
            end if
            qhi = q
            rhi = r
        end do
        ! wire tension from the tip shear: Q = P.n with P = -T r/|r|
        nrm = (-shot%z_end(IX)*(-sin(shot%z_end(IPSI))) - shot%z_end(IY)*cos(shot%z_end(IPSI))) &
              /hypot(shot%z_end(IX), shot%z_end(IY))
        tnorm = q/nrm
        call curvature_from_moment(prob%chain%ei(1), prob%chain%cubic(1), &
                                   q*prob%total_length, u(1), ok)
        u(2) = q
        u(3) = 0.0_dp
        u(4) = tnorm
        if (target_a > 0.0_dp) then
            call newton(prob, u, no_wrt, opts, its, sol%residual, shot_out, stat)
        else
            call newton(prob, u, wrt, opts, its, sol%residual, shot_out, stat)
        end if
        sol%newton_iterations = its
        sol%load_steps = 1
        if (stat%code /= STATUS_OK) return
        if (target_a > 0.0_dp) then
            call continuation(prob, opts, u, 0.0_dp, target_a, .true., shot_out, sol, stat)
        end if

    contains

        !> Tip radius of the shear-only shape with constant shear qq; the
        !! moment is linear, M(s) = qq (L - s), so k(0) follows from the root moment.
        subroutine wire_radius(qq, radius, sh, good)
            real(dp), intent(in) :: qq
            real(dp), intent(out) :: radius
            type(shot_t), intent(inout) :: sh
            logical, intent(out) :: good
            real(dp) :: uu(3), k0
            type(status_t) :: st
            call curvature_from_moment(prob%chain%ei(1), prob%chain%cubic(1), &
                                       qq*prob%total_length, k0, good)
            radius = huge(1.0_dp)
            if (.not. good) return
            uu = [k0, qq, 0.0_dp]
            call shoot(prob, uu, no_wrt, .false., opts, sh, st)
            good = st%code == STATUS_OK
            if (good) radius = hypot(sh%z_end(IX), sh%z_end(IY))
        end subroutine wire_radius
    end subroutine solve_wire

    !> Natural-parameter continuation from theta0 (solution in u) to theta1,
    !! on the tip load factor or (coupling = .true.) on axial_coupling, with
    !! step halving on failure and secant prediction.
    subroutine continuation(prob, opts, u, theta0, theta1, coupling, shot, sol, stat)
        type(problem_t), intent(inout) :: prob
        type(static_options_t), intent(in) :: opts
        real(dp), intent(inout) :: u(:)
        type(shot_t), intent(inout) :: shot
        real(dp), intent(in) :: theta0, theta1
        logical, intent(in) :: coupling
        type(static_solution_t), intent(inout) :: sol
        type(status_t), intent(inout) :: stat
        real(dp) :: theta, dtheta, ttry, uprev(size(u)), utry(size(u)), thprev, resid
        type(status_t) :: trial
        integer :: steps, its
        integer :: no_wrt(0)
        logical :: have_prev

        theta = theta0
        dtheta = (theta1 - theta0)/4.0_dp
        have_prev = .false.
        thprev = theta0
        uprev = u
        steps = 0
        do while (theta /= theta1)
            steps = steps + 1
            if (steps > opts%max_load_steps .or. &
                abs(dtheta) < 1.0e-7_dp*abs(theta1 - theta0)) then
                call set_status(stat, ERR_NO_CONVERGENCE, 'static continuation', &
                                trim(merge('axial_coupling', 'load factor   ', coupling))// &
                                ' stalled at '//fmt_real(theta)//' of '//fmt_real(theta1)// &
                                ' after '//fmt_int(steps)//' steps ('//load_text(prob%load)// &
                                '); last scaled residual '//fmt_real(resid))
                return
            end if
            ttry = theta + dtheta
            if ((theta1 - ttry)*(theta1 - theta0) <= 0.0_dp) ttry = theta1
            if (have_prev) then
                utry = u + (u - uprev)*(ttry - theta)/(theta - thprev)
            else
                utry = u
            end if
            call set_theta(ttry)
            trial%code = STATUS_OK
            call newton(prob, utry, no_wrt, opts, its, resid, shot, trial)
            if (trial%code == STATUS_OK) then
                uprev = u
                thprev = theta
                have_prev = .true.
                u = utry
                theta = ttry
                sol%newton_iterations = sol%newton_iterations + its
                sol%residual = resid
                if (its <= 4) dtheta = 1.5_dp*dtheta
            else
                dtheta = 0.5_dp*dtheta
            end if
        end do
        sol%load_steps = sol%load_steps + steps

    contains

        subroutine set_theta(t)
            real(dp), intent(in) :: t
            if (coupling) then
                prob%chain%axial_coupling = t
            else
                prob%load_factor = t
            end if
        end subroutine set_theta

    end subroutine continuation

    !> Outputs and sensitivities at the converged unknowns (Eq. 44-51).
    subroutine finish(prob, u, wrt, shot, sol, stat)
        type(problem_t), intent(in) :: prob
        real(dp), intent(in) :: u(:)
        integer, intent(in) :: wrt(:)
        type(shot_t), intent(in) :: shot
        type(static_solution_t), intent(inout) :: sol
        type(status_t), intent(inout) :: stat
        real(dp) :: g(prob%nu), dg_dz(prob%nu, NZ), dg_dt(prob%nu), tension
        real(dp) :: jac(prob%nu, prob%nu), rhs_p(prob%nu, size(wrt))
        real(dp) :: dz_end(NZ, size(wrt)), dz_elbow(NZ, size(wrt)), du(prob%nu, size(wrt))
        real(dp) :: k0, d0, nan
        integer :: nw, nb, j, p

        nw = size(wrt)
        nb = prob%chain%nbeams
        tension = 0.0_dp
        if (prob%nu == 4) tension = u(4)
        call tip_residual(prob, shot%z_end, tension, g, dg_dz, dg_dt)
        jac = 0.0_dp
        jac(:, 1:NSHOOT) = matmul(dg_dz, shot%v_end(:, 1:NSHOOT))
        if (prob%nu == 4) jac(:, 4) = dg_dt
        ! implicit function theorem: J du/dp = -(dg/dz dz/dp|u + explicit dg/dp)
        rhs_p = -matmul(dg_dz, shot%v_end(:, NSHOOT + 1:))
        do j = 1, nw
            p = wrt(j)
            if (p == param_index_beam(nb, nb, IB_EI)) &
                rhs_p(1, j) = rhs_p(1, j) - shot%z_end(IK)/prob%moment_scale
            if (p == param_index_beam(nb, nb, IB_C)) &
                rhs_p(1, j) = rhs_p(1, j) - shot%z_end(IK)**3/prob%moment_scale
        end do
        if (nw > 0) then
            call solve_dense(jac, rhs_p, stat)
            if (stat%code /= STATUS_OK) then
                call set_status(stat, ERR_SINGULAR, 'static sensitivities', 'the tip '// &
                                'conditions are singular at the solution (limit point?)')
                return
            end if
        end if
        du = rhs_p
        dz_end = shot%v_end(:, NSHOOT + 1:) + matmul(shot%v_end(:, 1:NSHOOT), du(1:NSHOOT, :))
        dz_elbow = shot%v_joint(:, NSHOOT + 1:, 1) + &
                   matmul(shot%v_joint(:, 1:NSHOOT, 1), du(1:NSHOOT, :))

        nan = ieee_value(1.0_dp, ieee_quiet_nan)
        allocate (sol%doutputs(NOUT, nw), source=0.0_dp)
        ! x, y, angle of the tip and of the elbow: the states IX:IPSI, in order
        sol%outputs(OUT_X_TIP:OUT_TIP_ANGLE) = shot%z_end(IX:IPSI)
        sol%doutputs(OUT_X_TIP:OUT_TIP_ANGLE, :) = dz_end(IX:IPSI, :)
        if (prob%nu == 4) then
            sol%outputs(OUT_WIRE_FORCE) = tension
            sol%doutputs(OUT_WIRE_FORCE, :) = du(4, :)
        else
            sol%outputs(OUT_WIRE_FORCE) = nan
            sol%doutputs(OUT_WIRE_FORCE, :) = nan
        end if
        if (nb >= 2) then
            sol%outputs(OUT_X_ELBOW:OUT_ELBOW_ANGLE) = shot%z_joint(IX:IPSI, 1)
            sol%doutputs(OUT_X_ELBOW:OUT_ELBOW_ANGLE, :) = dz_elbow(IX:IPSI, :)
        else
            sol%outputs(OUT_X_ELBOW:OUT_ELBOW_ANGLE) = nan
            sol%doutputs(OUT_X_ELBOW:OUT_ELBOW_ANGLE, :) = nan
        end if
        k0 = u(1)
        d0 = tangent_stiffness(prob%chain%ei(1), prob%chain%cubic(1), k0)
        sol%outputs(OUT_ROOT_MOMENT) = prob%chain%ei(1)*k0 + prob%chain%cubic(1)*k0**3
        sol%doutputs(OUT_ROOT_MOMENT, :) = d0*du(1, :)
        do j = 1, nw
            p = wrt(j)
            if (p == param_index_beam(nb, 1, IB_EI)) &
                sol%doutputs(OUT_ROOT_MOMENT, j) = sol%doutputs(OUT_ROOT_MOMENT, j) + k0
            if (p == param_index_beam(nb, 1, IB_C)) &
                sol%doutputs(OUT_ROOT_MOMENT, j) = sol%doutputs(OUT_ROOT_MOMENT, j) + k0**3
        end do
        sol%unknowns = 0.0_dp
        sol%unknowns(1:prob%nu) = u
        sol%dunknowns = du
    end subroutine finish

    !> Shape on the global arc positions s (ascending, within [0, total length])
    !! for converged unknowns: columns x, y, psi, bending moment.
    subroutine static_shape(chain, load, unknowns, opts, s, x, y, psi, moment, stat)
        type(chain_t), intent(in) :: chain
        type(static_load_t), intent(in) :: load
        real(dp), intent(in) :: unknowns(4)
        type(static_options_t), intent(in) :: opts
        real(dp), intent(in) :: s(:)
        real(dp), intent(out) :: x(:), y(:), psi(:), moment(:)
        type(status_t), intent(inout) :: stat
        type(problem_t) :: prob
        type(shot_t) :: shot
        real(dp) :: zs(NZ, size(s)), total
        integer :: no_wrt(0), j, beam
        real(dp) :: s0

        total = sum(chain%length)
        if (size(s) > 0) then
            if (s(1) < 0.0_dp .or. s(size(s)) > total*(1.0_dp + 1.0e-12_dp) .or. &
                any(s(2:) < s(:size(s) - 1))) then
                call set_status(stat, ERR_INPUT, 'static_shape', 'arc positions must '// &
                                'ascend within [0, '//fmt_real(total)//']')
                return
            end if
        end if
        call setup_problem(chain, load, prob)
        call shoot(prob, unknowns(1:3), no_wrt, .false., opts, shot, stat, s, zs)
        if (stat%code /= STATUS_OK) return
        x = zs(IX, :)
        y = zs(IY, :)
        psi = zs(IPSI, :)
        ! moment from the curvature with the law of the beam the station is on
        s0 = 0.0_dp
        beam = 1
        do j = 1, size(s)
            do while (beam < chain%nbeams .and. s(j) > s0 + chain%length(beam))
                s0 = s0 + chain%length(beam)
                beam = beam + 1
            end do
            moment(j) = chain%ei(beam)*zs(IK, j) + chain%cubic(beam)*zs(IK, j)**3
        end do
    end subroutine static_shape

    !> The state z = (x, y, psi, k, Q, N) at stations (beam(i), s(i): arc
    !! length s(i) from the root of beam(i), 0 <= s <= L) of a converged
    !! solution sol (solve_static with the same wrt), and its derivatives
    !! dz(:, i, j) = d z / d params(wrt(j)): one more shot with the
    !! variational columns recorded at the stations, combined with the
    !! unknowns' sensitivities (implicit function theorem, Eq. 44-51) as for
    !! the tip. A station at s = 0 of beam b > 1 reads the state after the
    !! joint; lengths of the beams before b move it (their columns), L_b
    !! does not (the station is a material point).
    subroutine static_stations(chain, load, sol, wrt, opts, beam, s, z, dz, stat)
        type(chain_t), intent(in) :: chain
        type(static_load_t), intent(in) :: load
        type(static_solution_t), intent(in) :: sol
        integer, intent(in) :: wrt(:), beam(:)
        real(dp), intent(in) :: s(:)
        type(static_options_t), intent(in) :: opts
        real(dp), intent(out) :: z(:, :), dz(:, :, :)
        type(status_t), intent(inout) :: stat
        type(problem_t) :: prob
        type(shot_t) :: shot
        real(dp), allocatable :: vst(:, :, :), zst(:, :), local(:)
        integer, allocatable :: on(:), order(:)
        real(dp) :: zz(NZ)
        integer :: nb, ncol, i, k, m, nw
        z = 0.0_dp
        dz = 0.0_dp
        nb = chain%nbeams
        nw = size(wrt)
        call setup_problem(chain, load, prob)
        ncol = NSHOOT + nw
        call size_shot(shot, ncol, nb)
        shot%work%v = 0.0_dp
        shot%steps = 0
        call root_state(prob%chain, sol%unknowns(1:NSHOOT), wrt, NSHOOT, .true., zz, shot%work%v)
        do i = 1, nb
            call column_kinds(nb, i, wrt, NSHOOT, shot%work%colkind)
            on = pack([(k, k=1, size(beam))], beam == i)
            ! ascending arc length on this beam
            order = on
            do k = 2, size(order)
                m = k
                do while (m > 1)
                    if (s(order(m - 1)) <= s(order(m))) exit
                    order([m - 1, m]) = order([m, m - 1])
                    m = m - 1
                end do
            end do
            ! stations at the beam's root: the state before integrating
            m = 0
            do k = 1, size(order)
                if (s(order(k)) > 0.0_dp) exit
                m = k
                call record(order(k), zz, shot%work%v)
            end do
            order = order(m + 1:)
            local = min(s(order), chain%length(i))
            allocate (zst(NZ, size(order)), vst(NZ, ncol, size(order)))
            call integrate_beam(prob, i, zz, IX, shot%work%v, shot%work%colkind, local, zst, opts, &
                                shot%steps, shot%work%w, shot%work%vs, stat, vst)
            if (stat%code /= STATUS_OK) return
            do k = 1, size(order)
                call record(order(k), zst(:, k), vst(:, :, k))
            end do
            deallocate (zst, vst)
            call add_length_columns(prob%chain, i, wrt, NSHOOT, zz, shot%work%v)
            if (i == nb) exit
            call cross_joint(prob%chain, i, wrt, NSHOOT, zz, shot%work, stat)
            if (stat%code /= STATUS_OK) return
        end do
    contains
        subroutine record(k, zk, vk)
            integer, intent(in) :: k
            real(dp), intent(in) :: zk(:), vk(:, :)
            z(:, k) = zk
            if (nw > 0) dz(:, k, :) = vk(:, NSHOOT + 1:) + &
                                      matmul(vk(:, 1:NSHOOT), sol%dunknowns(1:NSHOOT, :))
        end subroutine record
    end subroutine static_stations
end module beamid_arclength
