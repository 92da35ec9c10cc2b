!> Time integrators for the finite element dynamics of beamid_dynamics.
!!
!! - RK4: the classical fixed-step Runge-Kutta scheme of the dissertation
!!   (Eq. 99, 107; dt = 1e-5 s), with the work of every effect integrated as
!!   extra state components (Eq. 121-122, 156). Each output time is reached
!!   exactly: the interval between outputs is cut into ceil(span/dt) equal steps.
!! - Implicit (default): the three-stage Radau IIA collocation method (order 5,
!!   L-stable; Hairer and Wanner, Solving ODEs II, IV.8) with simplified Newton
!!   iterations on the hand-coded Jacobian and error-controlled step sizes.
!!   The stage system is decoupled by the eigenvalues of the Radau matrix into
!!   one real and one complex linear system (gamma/h - J) and (mu/h - J). For
!!   the second-order structure J = [0 I; -M^-1 K, -M^-1 C] each reduces to one
!!   banded system of order n (docs/theory_dynamics.md):
!!       (lam^2 M + lam C + K) x = M s + (lam M + C) r,   y = lam x - r,
!!   so every solve is linear in the number of elements. Symmetric iteration
!!   matrices (no motor lag) are factored as L D L^T without pivoting when
!!   the pivots allow it, others by band LU with partial pivoting
!!   (docs/theory_dynamics.md). The factorized matrices are kept in radau_t
!!   after each step; they are the iteration matrices a staggered
!!   forward-sensitivity step (Eq. 135-140) reuses. Work lines are integrated by the collocation quadrature on the
!!   converged stages, so energy - work is the numerical dissipation.
module beamid_integrators
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_INPUT, ERR_NO_CONVERGENCE, &
                             ERR_NUMERIC, fmt_int, fmt_real
    use beamid_dynamics, only: dyn_system_t, dyn_eval, dyn_cmass, dyn_to_physical, &
                               dyn_to_coords, dyn_energy, dyn_torque, &
                               dyn_switch, dyn_fric_dof, dyn_rot_mv, dyn_mass, &
                               FRICTION_SIGN, dyn_param_t, dyn_velocity_coupled, &
                               dyn_dmass_mv, dyn_dmass_dq_mv, dyn_constrain, dyn_param_dcap, &
                               dyn_breakpoints, dyn_dbreak, &
                               DP_NONE
    use beamid_band, only: band_lu_t, zband_lu_t, band_factor, band_solve, zband_factor, &
                           zband_solve, ldlt_real, ldlt_cplx, ldlt_solve_real, ldlt_solve_cplx, &
                           band_mv, ldlt_solve, kc_mv, ldlt_solve_real_many, ldlt_solve_cplx_many
    implicit none
    private

    public :: integ_opts_t, integ_stats_t, history_t, radau_t, event_t
    public :: EVENT_START, EVENT_ZERO_VELOCITY, EVENT_UNSTICK
    public :: integrate, METHOD_RK4, METHOD_IMPLICIT
    public :: integ_rate_sens

    integer, parameter :: METHOD_RK4 = 0, METHOD_IMPLICIT = 1
    !> The low-rank correction of a solve (lr_real, lr_cplx).
    interface lr_apply
        module procedure lr_real, lr_cplx
    end interface lr_apply
    !> Kinds of friction events: the decision at the start (components at
    !! rest at t = 0), a sliding component's velocity reaching zero (it
    !! reverses or sticks), a sticking component's constraint force reaching
    !! mu N (it starts to slide).
    integer, parameter :: EVENT_START = 0, EVENT_ZERO_VELOCITY = 1, EVENT_UNSTICK = 2

    !> A friction switch (Eq. 101-102 as events). The record is what a
    !! sensitivity jump condition needs (docs/theory_dynamics.md): the time,
    !! the component (j = 2 (k - 1) + c: point k, c = 1 u, c = 2 w), its
    !! discrete mode before and after (+-1 sliding, 0 sticking) and the
    !! friction force on it just before and just after (N; a sticking
    !! component's is its constraint force). The rates jump by
    !! M^-1 e_i (force_after - force_before) on that component.
    type :: event_t
        real(dp) :: t = 0.0_dp
        integer :: comp = 0, kind = 0, before = 0, after = 0
        real(dp) :: force_before = 0.0_dp, force_after = 0.0_dp
        ! No per-event state vectors here (a rate jump of the whole state was
        ! stored and never read): a chattering run records an event per step,
        ! and the list must stay small per record.
    end type event_t

    !> Controls of the integrators.
    type :: integ_opts_t
        integer :: method = METHOD_IMPLICIT
        real(dp) :: dt = 1.0e-5_dp       !< RK4 step (s)
        real(dp) :: rtol = 1.0e-9_dp     !< implicit: relative tolerance
        real(dp) :: atol = 1.0e-9_dp     !< implicit: absolute tolerance (m, rad)
        real(dp) :: h0 = 1.0e-4_dp       !< implicit: first step (s)
        integer :: max_steps = 50000000
        !> where the caller watches the run: progress(1) is set to each output
        !! time once it is reached (unassociated: nobody watches)
        real(dp), pointer :: progress(:) => null()
    end type integ_opts_t

    !> What an integration did.
    type :: integ_stats_t
        integer :: steps = 0, rejected = 0, fevals = 0, jevals = 0, newton = 0
        integer :: factorizations = 0
        integer :: events = 0       !< friction switches (event_t records)
        integer :: event_steps = 0  !< steps cut short or redone to land on one
        integer :: sens_passes = 0  !< implicit sensitivity iteration passes (all parameters)
    end type integ_stats_t

    !> Time histories at the output times (columns).
    type :: history_t
        real(dp), allocatable :: y(:, :)        !< state (q, v, x)
        real(dp), allocatable :: torque(:)      !< motor torque (N m)
        real(dp), allocatable :: kinetic(:), potential(:)
        real(dp), allocatable :: work(:, :)     !< work lines (nwork x nt)
        type(event_t), allocatable :: events(:) !< friction switches, in time order
        integer :: nevents = 0
    end type history_t

    !> Iteration matrices of the Radau step, kept factorized for reuse.
    type :: radau_t
        real(dp) :: h = 0.0_dp                  !< step they belong to
        real(dp), allocatable :: mb(:, :), kb(:, :), cb(:, :)
        real(dp), allocatable :: b(:), p(:), d(:)
        real(dp) :: e = 0.0_dp
        type(band_lu_t) :: lu1                  !< gamma/h - J (real)
        type(zband_lu_t) :: lu2                 !< mu/h - J (complex)
        logical :: have_mass = .false.          !< mb holds the constant M
        !> M0 again, its nonzeros by rows (compressed sparse rows): the
        !! consistent mass couples w with w and u with u only, so half of the
        !! band is zero and the M-form products (several per Newton
        !! iteration) skip it
        integer, allocatable :: m_start(:), m_col(:)
        real(dp), allocatable :: m_val(:)
        real(dp), allocatable :: a1(:, :)       !< gamma/h M + C (band)
        complex(dp), allocatable :: a2(:, :)    !< mu/h M + C (band)
        real(dp), allocatable :: rhs(:), tmp(:) !< work (n)
        !> symmetric iteration matrices (no motor lag, symmetric K and C: the
        !! usual case) are factored as L D L^T without pivoting instead:
        !! gamma/h-matrix in s1, mu/h-matrix in s2 (lower band, s(1 + i - j, j)
        !! = A(i, j), L and D in place); lu1, lu2 are then not used
        logical :: sym = .false.
        logical :: m_sym = .false.              !< M0 is symmetric
        real(dp), allocatable :: s1(:, :)
        complex(dp), allocatable :: s2(:, :)
        complex(dp), allocatable :: zrhs(:)
        !> sticking friction components: their free indices, held at rest
        !! (rows and columns of the iteration matrices pinned to the identity)
        integer :: nst = 0
        integer, allocatable :: stuck(:), stuckc(:)   !< free index, component j
        !> rotary inertia without modal coordinates: M(q) = M_c + R(q), the
        !! iteration matrices use M0 = M(q) at the Jacobian's state qjac
        logical :: rot = .false.
        real(dp), allocatable :: qjac(:)
        !> K or C not symmetric in a few rows only (the gyroscopic terms of a
        !! mass's rotary inertia, Eq. 132, the motor's torque on the tip
        !! slopes: one 2 x 2 block per mass): A = A_L + E_R D with A_L the
        !! symmetric matrix of A's lower half (factored as L D L^T in s1, s2)
        !! and D the differences of the upper half in the rows R; the solves
        !! add the Sherman-Morrison-Woodbury correction, so they stay exact
        integer :: nlr = 0                      !< rows R (0: no correction)
        integer :: nle = 0                      !< nonzeros of D
        integer, allocatable :: lr_row(:)       !< R (free indices)
        integer, allocatable :: le_k(:), le_col(:)   !< a nonzero's row (in R), column
        real(dp), allocatable :: le_d1(:)       !< its value in the real matrix
        complex(dp), allocatable :: le_d2(:)    !< in the complex matrix
        real(dp), allocatable :: lr_w1(:, :)    !< A1_L^-1 E_R (n x nlr)
        complex(dp), allocatable :: lr_w2(:, :) !< A2_L^-1 E_R
        complex(dp), allocatable :: lr_c1(:, :), lr_c2(:, :)   !< (I + D W)^-1
    end type radau_t

    !> At most this many rows of the iteration matrices may be unsymmetric
    !! for the L D L^T path with its low-rank correction (two masses, a
    !! motor: two rows), and four times as many nonzeros in them
    integer, parameter :: LR_MAX = 8, LE_MAX = 4*LR_MAX
    !> largest entry of (I + D W)^-1 the correction accepts (else band LU)
    real(dp), parameter :: LR_COND = 1.0e6_dp

    !> Work arrays of the implicit sensitivity step, allocated once per run
    !! (stage Jacobians, parameter derivatives of the forces, the stage
    !! sensitivities of every parameter and the residuals of the active ones).
    type :: sens_work_t
        real(dp), allocatable :: kb(:, :, :), cb(:, :, :), b(:, :), p(:, :), d(:, :)
        real(dp), allocatable :: acc(:, :), cst(:, :, :), dz(:, :, :), r(:, :, :)
        real(dp), allocatable :: zd(:), t(:, :), fp(:), ys(:), w1(:, :), dels(:, :)
        real(dp), allocatable :: errold(:), wq(:, :), wv(:, :)
        !> passes after the first (sens_update): the displacement corrections
        !! of the active columns (n x na x 3) and K0 - K(Y_i) of the stages
        real(dp), allocatable :: dlq(:, :, :), kd(:, :, :)
        !> the stage accelerations (D dZ)_i / h of the active columns (velocity
        !! rows) and their mass products M0 (D dZ)_i / h
        real(dp), allocatable :: zv(:, :), tm(:, :), t3(:, :)
        !> each column's last observed contraction of the pass loop (0: none
        !! yet), carried across steps as CVODES carries its rate estimate
        real(dp), allocatable :: thc(:)
        complex(dp), allocatable :: w2(:, :)
        !> the many-column solves' right-hand sides as rows (nw x n)
        real(dp), allocatable :: bt1(:)
        complex(dp), allocatable :: bt2(:)
        integer, allocatable :: act(:)
        !> the nonzero columns jr(1, j):jr(2, j) of a parameter's dM/dp (0: not
        !! yet scanned)
        integer, allocatable :: jr(:, :)
    end type sens_work_t

    character(len=*), parameter :: RADAU_WHERE = 'implicit'
    !> RK4: a state component (m, rad, m/s, rad/s, N m) beyond this has diverged
    real(dp), parameter :: RK_DIVERGED = 1.0e20_dp

    !> What the steps of run_radau share: the tableau, the system with its
    !! friction modes and factored iteration matrices, the state, the stages
    !! and the step controller's memory (hh: this step, h: the next one).
    type :: radau_run_t
        real(dp) :: a(3, 3) = 0.0_dp, dmat(3, 3) = 0.0_dp, gam = 0.0_dp
        real(dp) :: ti1(3) = 0.0_dp, tr(3) = 0.0_dp
        complex(dp) :: mu = (0.0_dp, 0.0_dp), ti2(3) = (0.0_dp, 0.0_dp), &
                       tc(3) = (0.0_dp, 0.0_dp)
        type(radau_t) :: it
        type(dyn_system_t) :: es
        integer :: n = 0
        real(dp), allocatable :: y(:), z(:, :), zprev(:, :), fz(:, :), zd(:, :), f0(:), f3(:), &
                                 e0(:), ev(:), iscal(:), w1(:), dz(:, :), work(:), pw(:, :), &
                                 ytmp(:), ys(:)
        complex(dp), allocatable :: w2(:)
        real(dp), allocatable :: hold0(:), hst(:, :), acc3(:), rv(:)
        real(dp) :: t = 0.0_dp, h = 0.0_dp, hh = 0.0_dp, hprev = 0.0_dp, hnew = 0.0_dp
        real(dp) :: tiny_h = 0.0_dp, err = 0.0_dp, theta = 0.0_dp, dnorm = 0.0_dp
        real(dp) :: sev = 0.0_dp, hpend = 0.0_dp, hcut = 0.0_dp
        integer :: jev = 0, kev = 0, pend = 0, pkind = 0, nstall = 0
        logical :: first = .true., reject = .false., clipped = .false., have_prev = .false.
        logical :: have_f0 = .false., evon = .false., rot_slow = .false.
        logical :: may_reuse = .false., reused = .false.
        !> the stage times of the step (the third at the left limit of a
        !! breakpoint it lands on), the forcings' breakpoints, the next one's
        !! index, and whether the step is cut at one
        real(dp) :: ts(3) = 0.0_dp
        real(dp), allocatable :: bk(:)
        integer :: ib = 1
        logical :: atbreak = .false.
        logical :: sens = .false.                   !< forward sensitivities
        real(dp), allocatable :: fm(:), dtp(:), dzp(:, :, :)
        real(dp) :: hsp = 0.0_dp
        type(sens_work_t) :: sws
    end type radau_run_t

    ! Radau IIA (3 stages) nodes, stiffly accurate weights b = A(3, :),
    ! and the embedded-error coefficients (Hairer-Wanner IV.8).
    real(dp), parameter :: SQ6 = sqrt(6.0_dp)
    real(dp), parameter :: C1 = (4.0_dp - SQ6)/10.0_dp, C2 = (4.0_dp + SQ6)/10.0_dp
    real(dp), parameter :: CNODE(3) = [C1, C2, 1.0_dp]
    real(dp), parameter :: DD(3) = [-(13.0_dp + 7.0_dp*SQ6)/3.0_dp, &
                                    (-13.0_dp + 7.0_dp*SQ6)/3.0_dp, -1.0_dp/3.0_dp]

contains

    !> Radau IIA matrix A, its inverse D, the eigenvalues gamma (real) and mu
    !! (complex, Im > 0) of D, and the eigenvector matrix T (D = T diag T^-1,
    !! columns normalized to a last entry 1) with its inverse.
    pure subroutine radau_tableau(a, dmat, gam, mu, t, ti)
        real(dp), intent(out) :: a(3, 3), dmat(3, 3), gam
        complex(dp), intent(out) :: mu, t(3, 3), ti(3, 3)
        complex(dp) :: lam(3), m(3, 3), det
        integer :: k, it
        a(1, :) = [(88.0_dp - 7.0_dp*SQ6)/360.0_dp, (296.0_dp - 169.0_dp*SQ6)/1800.0_dp, &
                   (-2.0_dp + 3.0_dp*SQ6)/225.0_dp]
        a(2, :) = [(296.0_dp + 169.0_dp*SQ6)/1800.0_dp, (88.0_dp + 7.0_dp*SQ6)/360.0_dp, &
                   (-2.0_dp - 3.0_dp*SQ6)/225.0_dp]
        a(3, :) = [(16.0_dp - SQ6)/36.0_dp, (16.0_dp + SQ6)/36.0_dp, 1.0_dp/9.0_dp]
        call cinv3(cmplx(a, 0.0_dp, dp), m)
        dmat = real(m, dp)
        ! eigenvalues of D: Newton on det(D - lam I) from the known values
        lam = [cmplx(3.6378342527444957_dp, 0.0_dp, dp), &
               cmplx(2.6810828736277521_dp, 3.0504301992474106_dp, dp), &
               cmplx(2.6810828736277521_dp, -3.0504301992474106_dp, dp)]
        do k = 1, 3
            do it = 1, 3
                lam(k) = lam(k) - char_poly(dmat, lam(k))/char_dpoly(dmat, lam(k))
            end do
        end do
        gam = real(lam(1), dp)
        mu = lam(2)
        ! eigenvectors with last component 1: first two rows of (D - lam I) v = 0
        do k = 1, 3
            m = cmplx(dmat, 0.0_dp, dp)
            m(1, 1) = m(1, 1) - lam(k)
            m(2, 2) = m(2, 2) - lam(k)
            det = m(1, 1)*m(2, 2) - m(1, 2)*m(2, 1)
            t(1, k) = (-m(1, 3)*m(2, 2) + m(2, 3)*m(1, 2))/det
            t(2, k) = (-m(1, 1)*m(2, 3) + m(2, 1)*m(1, 3))/det
            t(3, k) = (1.0_dp, 0.0_dp)
        end do
        t(:, 1) = cmplx(real(t(:, 1), dp), 0.0_dp, dp)
        call cinv3(t, ti)
    end subroutine radau_tableau

    pure complex(dp) function char_poly(d, lam)
        real(dp), intent(in) :: d(3, 3)
        complex(dp), intent(in) :: lam
        complex(dp) :: m(3, 3)
        m = cmplx(d, 0.0_dp, dp)
        m(1, 1) = m(1, 1) - lam
        m(2, 2) = m(2, 2) - lam
        m(3, 3) = m(3, 3) - lam
        char_poly = m(1, 1)*(m(2, 2)*m(3, 3) - m(2, 3)*m(3, 2)) &
                    - m(1, 2)*(m(2, 1)*m(3, 3) - m(2, 3)*m(3, 1)) &
                    + m(1, 3)*(m(2, 1)*m(3, 2) - m(2, 2)*m(3, 1))
    end function char_poly

    pure complex(dp) function char_dpoly(d, lam)
        real(dp), intent(in) :: d(3, 3)
        complex(dp), intent(in) :: lam
        complex(dp), parameter :: eps = (1.0e-7_dp, 0.0_dp)
        char_dpoly = (char_poly(d, lam + eps) - char_poly(d, lam - eps))/(2.0_dp*eps)
    end function char_dpoly

    pure subroutine cinv3(m, mi)
        complex(dp), intent(in) :: m(3, 3)
        complex(dp), intent(out) :: mi(3, 3)
        complex(dp) :: det
        mi(1, 1) = m(2, 2)*m(3, 3) - m(2, 3)*m(3, 2)
        mi(1, 2) = m(1, 3)*m(3, 2) - m(1, 2)*m(3, 3)
        mi(1, 3) = m(1, 2)*m(2, 3) - m(1, 3)*m(2, 2)
        mi(2, 1) = m(2, 3)*m(3, 1) - m(2, 1)*m(3, 3)
        mi(2, 2) = m(1, 1)*m(3, 3) - m(1, 3)*m(3, 1)
        mi(2, 3) = m(1, 3)*m(2, 1) - m(1, 1)*m(2, 3)
        mi(3, 1) = m(2, 1)*m(3, 2) - m(2, 2)*m(3, 1)
        mi(3, 2) = m(1, 2)*m(3, 1) - m(1, 1)*m(3, 2)
        mi(3, 3) = m(1, 1)*m(2, 2) - m(1, 2)*m(2, 1)
        det = m(1, 1)*mi(1, 1) + m(1, 2)*mi(2, 1) + m(1, 3)*mi(3, 1)
        mi = mi/det
    end subroutine cinv3

    !> Integrate from the state y0 at t = 0 to every output time t_out
    !! (ascending, >= 0) and record the history with its energy ledger.
    !! With `pars`, also the forward sensitivities dy/dp of the state with
    !! respect to each parameter, from s0 = dy0/dp, into dstates(:, k, j)
    !! (full model only).
    subroutine integrate(sys, y0, t_out, opts, hist, stats, stat, pars, s0, dstates)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: y0(:), t_out(:)
        type(integ_opts_t), intent(in) :: opts
        type(history_t), intent(out) :: hist
        type(integ_stats_t), intent(out) :: stats
        type(status_t), intent(inout) :: stat
        type(dyn_param_t), intent(in), optional :: pars(:)
        real(dp), intent(in), optional :: s0(:, :)
        real(dp), allocatable, intent(out), optional :: dstates(:, :, :)
        real(dp), allocatable :: sm(:, :)
        character(len=*), parameter :: where = 'integrate'
        real(dp), allocatable :: yc0(:)
        integer :: nt, k
        nt = size(t_out)
        if (size(y0) /= sys%nstate) then
            call set_status(stat, ERR_INPUT, where, 'state has '//fmt_int(size(y0))// &
                            ' entries, expected '//fmt_int(sys%nstate))
            return
        end if
        if (nt < 1) then
            call set_status(stat, ERR_INPUT, where, 'no output times')
            return
        end if
        if (.not. all(ieee_is_finite(t_out)) .or. t_out(1) < 0.0_dp) then
            call set_status(stat, ERR_INPUT, where, 't_out must be finite and >= 0')
            return
        end if
        do k = 2, nt
            if (t_out(k) < t_out(k - 1)) then
                call set_status(stat, ERR_INPUT, where, 't_out is not ascending at index '// &
                                fmt_int(k)//' ('//fmt_real(t_out(k))//' after '// &
                                fmt_real(t_out(k - 1))//')')
                return
            end if
        end do
        if (opts%method == METHOD_RK4 .and. opts%dt > 0.0_dp .and. ieee_is_finite(opts%dt)) then
            ! a fixed step that would take longer than anyone waits is bad input
            if (t_out(nt)/opts%dt > real(opts%max_steps, dp)) then
                call set_status(stat, ERR_INPUT, where, 'dt = '//fmt_real(opts%dt)// &
                                ' s needs '//fmt_real(t_out(nt)/opts%dt)// &
                                ' RK4 steps to reach t = '//fmt_real(t_out(nt))// &
                                ' s, more than the bound of '//fmt_int(opts%max_steps)// &
                                ' steps: use a larger dt or the implicit integrator')
                return
            end if
        end if
        allocate (hist%y(sys%nstate, nt), hist%torque(nt), hist%kinetic(nt), &
                  hist%potential(nt), hist%work(sys%nwork, nt), source=0.0_dp, stat=k)
        if (k /= 0) then
            call set_status(stat, ERR_INPUT, where, fmt_int(nt)//' output times need '// &
                            fmt_real(8.0_dp*real(nt, dp)*real(sys%nstate + sys%nwork + 3, dp))// &
                            ' bytes for the history, which cannot be allocated')
            return
        end if
        if (present(pars)) then
            if (sys%modal) then
                call set_status(stat, ERR_INPUT, where, 'sensitivities are not available '// &
                                'in the truncated modal model')
                return
            end if
            if (.not. present(s0) .or. .not. present(dstates)) then
                call set_status(stat, ERR_INPUT, where, 'sensitivities need s0 and dstates')
                return
            end if
            if (size(s0, 1) /= sys%nstate .or. size(s0, 2) /= size(pars)) then
                call set_status(stat, ERR_INPUT, where, 's0 has shape '// &
                                fmt_int(size(s0, 1))//' x '//fmt_int(size(s0, 2))// &
                                ', expected '//fmt_int(sys%nstate)//' x '// &
                                fmt_int(size(pars)))
                return
            end if
            allocate (dstates(sys%nstate, nt, size(pars)), source=0.0_dp)
            sm = s0
        end if
        ! integration coordinates: q itself, or the modal coordinates (Eq. 127)
        allocate (yc0(sys%ncstate))
        call dyn_to_coords(sys, y0, yc0)
        select case (opts%method)
        case (METHOD_RK4)
            if (.not. (opts%dt > 0.0_dp .and. ieee_is_finite(opts%dt))) then
                call set_status(stat, ERR_INPUT, where, 'dt = '//fmt_real(opts%dt)// &
                                ', expected a positive step')
                return
            end if
            call run_rk4(sys, yc0, t_out, opts, hist, stats, stat, pars, sm, dstates)
        case (METHOD_IMPLICIT)
            if (.not. (opts%rtol > 0.0_dp .and. opts%atol > 0.0_dp .and. opts%h0 > 0.0_dp)) &
                then
                call set_status(stat, ERR_INPUT, where, 'rtol = '//fmt_real(opts%rtol)// &
                                ', atol = '//fmt_real(opts%atol)//', h0 = '// &
                                fmt_real(opts%h0)//': expected positive values')
                return
            end if
            call run_radau(sys, yc0, t_out, opts, hist, stats, stat, pars, sm, dstates)
        case default
            call set_status(stat, ERR_INPUT, where, 'method = '//fmt_int(opts%method)// &
                            ', expected 0 (rk4) or 1 (implicit)')
        end select
    end subroutine integrate

    !> Store output column k of the history (the physical state of the
    !! coordinate state yc).
    subroutine record(sys, yc, work, k, hist)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: yc(:), work(:)
        integer, intent(in) :: k
        type(history_t), intent(inout) :: hist
        real(dp) :: y(sys%nstate)
        integer :: n
        n = sys%n
        call dyn_to_physical(sys, yc, y)
        hist%y(:, k) = y
        hist%work(:, k) = work
        hist%torque(k) = dyn_torque(sys, y(1:n), y(n + 1:2*n), y(2*n + 1:))
        call dyn_energy(sys, y(1:n), y(n + 1:2*n), hist%kinetic(k), hist%potential(k))
    end subroutine record

    !> Rates of the RK4 state (y, work); `hold`: constraint forces of the
    !! sticking friction components.
    subroutine rk_rates(sys, t, s, ds, stat, hold)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t          !< time (s)
        real(dp), intent(in) :: s(:)
        real(dp), intent(out) :: ds(:)
        type(status_t), intent(inout) :: stat
        real(dp), intent(out), optional :: hold(:)
        integer :: m
        m = sys%ncstate
        call dyn_eval(sys, t, s(1:m), stat, rates=ds(1:m), power=ds(m + 1:), hold=hold)
    end subroutine rk_rates

    !> One classical RK4 step of size h from s, whose rates are k1.
    subroutine rk_step(sys, t, s, k1, h, k2, k3, k4, snew, stat, t_end)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t          !< time of s (s)
        real(dp), intent(in) :: s(:), k1(:), h
        real(dp), intent(inout) :: k2(:), k3(:), k4(:), snew(:)
        type(status_t), intent(inout) :: stat
        !> time of the last stage (default t + h; the left limit of a breakpoint)
        real(dp), intent(in), optional :: t_end
        real(dp) :: te
        te = t + h
        if (present(t_end)) te = t_end
        snew = s + 0.5_dp*h*k1
        call rk_rates(sys, t + 0.5_dp*h, snew, k2, stat)
        snew = s + 0.5_dp*h*k2
        call rk_rates(sys, t + 0.5_dp*h, snew, k3, stat)
        snew = s + h*k3
        call rk_rates(sys, te, snew, k4, stat)
        snew = s + (h/6.0_dp)*(k1 + 2.0_dp*(k2 + k3) + k4)
    end subroutine rk_step

    !> Is the event law on for this system (the sign law of Eq. 101-102 in
    !! the full model with some friction)?
    pure logical function events_on(sys)
        type(dyn_system_t), intent(in) :: sys
        events_on = sys%law == FRICTION_SIGN .and. .not. sys%modal .and. &
                    any(sys%fric /= 0.0_dp)
    end function events_on

    !> Append an event record, growing the list geometrically.
    subroutine add_event(hist, ev)
        type(history_t), intent(inout) :: hist
        type(event_t), intent(in) :: ev
        type(event_t), allocatable :: tmp(:)
        if (.not. allocated(hist%events)) allocate (hist%events(16))
        if (hist%nevents == size(hist%events)) then
            allocate (tmp(2*size(hist%events)))
            tmp(1:hist%nevents) = hist%events(1:hist%nevents)
            call move_alloc(tmp, hist%events)
        end if
        hist%nevents = hist%nevents + 1
        hist%events(hist%nevents) = ev
    end subroutine add_event

    !> Friction switch at the state y, time t (the component velocities that
    !! reached zero already set to 0): dyn_switch decides who sticks and who
    !! slides, each changed component is recorded. `jforce` (0: none) leaves
    !! the stick (EVENT_UNSTICK); `hold` in: the constraint forces before,
    !! out: after.
    subroutine apply_switch(es, y, t, kind, jforce, hold, hist, stats, stat)
        type(dyn_system_t), intent(inout) :: es
        real(dp), intent(in) :: y(:), t
        integer, intent(in) :: kind, jforce
        real(dp), intent(inout) :: hold(:)
        type(history_t), intent(inout) :: hist
        type(integ_stats_t), intent(inout) :: stats
        type(status_t), intent(inout) :: stat
        integer :: before(size(es%fmode)), j
        real(dp) :: fb(size(es%fmode)), cap
        type(event_t) :: ev
        before = es%fmode
        do j = 1, size(es%fmode)
            cap = es%fric((j + 1)/2)
            if (before(j) == 0) then
                fb(j) = hold(j)
            else
                fb(j) = -cap*before(j)
            end if
        end do
        call dyn_switch(es, t, y, jforce, hold, stat)
        if (stat%code /= 0) return
        do j = 1, size(es%fmode)
            if (es%fric((j + 1)/2) == 0.0_dp) cycle
            if (es%fmode(j) == before(j) .and. kind /= EVENT_START) cycle
            if (es%fmode(j) == before(j) .and. es%fmode(j) /= 0) cycle
            ev%t = t
            ev%comp = j
            ev%kind = kind
            if (kind /= EVENT_START .and. j == jforce) ev%kind = EVENT_UNSTICK
            ev%before = before(j)
            ev%after = es%fmode(j)
            ev%force_before = fb(j)
            if (es%fmode(j) == 0) then
                ev%force_after = hold(j)
            else
                ev%force_after = -es%fric((j + 1)/2)*es%fmode(j)
            end if
            if (kind == EVENT_START) ev%force_before = 0.0_dp
            call add_event(hist, ev)
            stats%events = stats%events + 1
        end do
    end subroutine apply_switch

    !> The friction modes at the start: components moving slide with the
    !! sign of their velocity; components at rest stick unless the other
    !! forces exceed mu N (then they slide the way they are pushed). This is
    !! sign(0) of Eq. 101 decided by the forces, not by a convention.
    subroutine start_modes(es, y, hold, hist, stats, stat)
        type(dyn_system_t), intent(inout) :: es
        real(dp), intent(in) :: y(:)
        real(dp), intent(out) :: hold(:)
        type(history_t), intent(inout) :: hist
        type(integ_stats_t), intent(inout) :: stats
        type(status_t), intent(inout) :: stat
        integer :: j
        real(dp) :: v
        do j = 1, size(es%fmode)
            v = y(es%n + dyn_fric_dof(es, j))
            es%fmode(j) = 0
            if (v > 0.0_dp) es%fmode(j) = 1
            if (v < 0.0_dp) es%fmode(j) = -1
        end do
        hold = 0.0_dp
        call apply_switch(es, y, 0.0_dp, EVENT_START, 0, hold, hist, stats, stat)
    end subroutine start_modes

    !> First root in (0, 1] of g(s) along a step, g > 0 before it: for a
    !! sliding component (kind EVENT_ZERO_VELOCITY) g = mode p(s), p the
    !! velocity; for a sticking one (EVENT_UNSTICK) g = cap - |p(s)|, p its
    !! constraint force. p(s) = p0 + sum_k dp(k) l_k(s) on the Radau nodes, or
    !! (herm) the cubic Hermite interpolant with end values p0, p1 and
    !! scaled end slopes d0, d1 (RK4). sroot = 0: g is already <= 0 just
    !! after the start (a component pushed the wrong way).
    pure subroutine first_root(kind, mode, cap, p0, dp3, herm, sroot, found)
        integer, intent(in) :: kind, mode
        real(dp), intent(in) :: cap, p0, dp3(3)
        logical, intent(in) :: herm
        real(dp), intent(out) :: sroot
        logical, intent(out) :: found
        integer, parameter :: NS = 16
        real(dp) :: g0, ga, gb, sa, sb, sm, gm
        integer :: k, it
        found = .false.
        sroot = 1.0_dp
        g0 = gfun(0.0_dp)
        sa = 0.0_dp
        ga = g0
        do k = 1, NS
            sb = real(k, dp)/real(NS, dp)
            gb = gfun(sb)
            if (ga <= 0.0_dp .and. k == 1 .and. gb < 0.0_dp) then
                ! at zero at the start (a component just switched, its velocity
                ! or excess force exactly zero) and below zero at the first
                ! sample: it may still go the right way first and turn within
                ! (0, sb) (a stiff axial vibration reverses the push within a
                ! fraction of the step). Look closer to the start, on a
                ! geometric grid: the first positive sample brackets the root.
                ! None down to 2^-50 of the step: wrong way from the start.
                sroot = 0.0_dp
                found = .true.
                if (g0 < 0.0_dp) return
                do it = 5, 50
                    sm = 0.5_dp**it
                    gm = gfun(sm)
                    if (gm > 0.0_dp) then
                        sa = sm
                        ga = gm
                        exit
                    end if
                    sb = sm
                end do
                if (ga <= 0.0_dp) return
            end if
            if (ga > 0.0_dp .and. gb <= 0.0_dp) then
                do it = 1, 60
                    sm = 0.5_dp*(sa + sb)
                    gm = gfun(sm)
                    if (gm > 0.0_dp) then
                        sa = sm
                    else
                        sb = sm
                    end if
                    if (sb - sa < 1.0e-15_dp) exit
                end do
                found = .true.
                sroot = sb
                return
            end if
            sa = sb
            ga = gb
        end do
    contains
        pure real(dp) function gfun(x)
            real(dp), intent(in) :: x
            real(dp) :: p, l(3), x2, x3
            if (herm) then
                ! dp3 = (p1, h p0', h p1')
                x2 = x*x
                x3 = x2*x
                p = (2*x3 - 3*x2 + 1)*p0 + (x3 - 2*x2 + x)*dp3(2) + (-2*x3 + 3*x2)*dp3(1) &
                    + (x3 - x2)*dp3(3)
            else
                l = lagrange(x)
                p = p0 + dp3(1)*l(1) + dp3(2)*l(2) + dp3(3)*l(3)
            end if
            if (kind == EVENT_ZERO_VELOCITY) then
                gfun = real(mode, dp)*p
            else
                gfun = cap - abs(p)
            end if
        end function gfun
    end subroutine first_root

    !> Classical RK4 with a fixed step (Eq. 99, 107). With the sign law,
    !! friction switches are events: a component velocity that changes sign
    !! within a step (cubic Hermite interpolant from the step's end values
    !! and rates), or a sticking component whose constraint force reaches
    !! mu N (linear in the step), ends the step there: it is redone to the
    !! event, the switch applied, and the output interval continues in
    !! equal steps no longer than dt.
    subroutine run_rk4(sys, y0, t_out, opts, hist, stats, stat, pars, sm, dstates)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: y0(:), t_out(:)
        type(integ_opts_t), intent(in) :: opts
        type(history_t), intent(inout) :: hist
        type(integ_stats_t), intent(inout) :: stats
        type(status_t), intent(inout) :: stat
        !> forward sensitivities: the parameters, S (in: at t = 0), S at t_out
        type(dyn_param_t), intent(in), optional :: pars(:)
        real(dp), intent(inout), optional :: sm(:, :)
        real(dp), intent(inout), optional :: dstates(:, :, :)
        real(dp), allocatable :: fm(:), dtp(:)
        logical :: sens
        type(dyn_system_t) :: es
        real(dp), allocatable :: s(:), k1(:), k2(:), k3(:), k4(:), sn(:), k1n(:)
        !> the L D L^T factors of the constant mass matrix, for the sensitivities
        real(dp), allocatable :: mldl(:, :)
        real(dp), allocatable :: hold(:), holdn(:)
        real(dp) :: t, h, hs, theta, hcap, tend, te
        integer :: m, n, k, nsub, i, jev, kind, ios, nstall, skipj, ib
        logical :: evon, atbreak
        !> the forcings' breakpoints (none without forcings)
        real(dp), allocatable :: bk(:)
        m = sys%ncstate
        n = sys%nc
        allocate (s(m + sys%nwork), k1(m + sys%nwork), k2(m + sys%nwork), &
                  k3(m + sys%nwork), k4(m + sys%nwork), sn(m + sys%nwork), &
                  k1n(m + sys%nwork), hold(2*sys%npt), holdn(2*sys%npt), stat=ios)
        if (ios /= 0) then
            call set_status(stat, ERR_INPUT, 'rk4', 'cannot allocate the RK4 work arrays ('// &
                            fmt_int(7*(m + sys%nwork))//' reals)')
            return
        end if
        es = sys
        evon = events_on(es)
        es%events = evon
        sens = present(pars)
        if (sens) allocate (fm(m), dtp(size(pars)))
        if (sens .and. .not. (es%rotary .or. es%modal)) call mass_ldlt(es, mldl)
        s = 0.0_dp
        s(1:m) = y0
        t = 0.0_dp
        hold = 0.0_dp
        if (evon) then
            call start_modes(es, s(1:m), hold, hist, stats, stat)
            if (stat%code /= 0) return
        end if
        call rk_rates(es, t, s, k1, stat, hold)
        stats%fevals = stats%fevals + 1
        if (stat%code /= 0) return
        nstall = 0
        skipj = 0
        hcap = opts%dt
        bk = dyn_breakpoints(es, 0.0_dp, t_out(size(t_out)))
        ib = 1
        do k = 1, size(t_out)
            ! step onto the forcings' breakpoints before t_out(k): segments
            ! [t, tend], the last step of each ending at the left limit of a
            ! breakpoint, the next segment starting from the rates after it
            seg: do
                tend = t_out(k)
                atbreak = .false.
                do while (ib <= size(bk))
                    if (bk(ib) > t + 1.0e-13_dp*max(1.0_dp, abs(t))) exit
                    ib = ib + 1
                end do
                if (ib <= size(bk)) then
                    if (bk(ib) <= t_out(k) + 1.0e-13_dp*max(1.0_dp, abs(t_out(k)))) then
                        tend = min(bk(ib), t_out(k))
                        atbreak = .true.
                    end if
                end if
                nsub = ceiling((tend - t)/opts%dt*(1.0_dp - 1.0e-12_dp))
                i = 0
                do while (i < nsub)
                    h = (tend - t)/real(nsub - i, dp)
                    if (hcap < opts%dt) h = min(h, hcap)
                    ! the last step onto a breakpoint ends at its left limit
                    te = t + h
                    if (atbreak) then
                        if (abs(tend - te) <= 1.0e-13_dp*max(1.0_dp, abs(tend))) &
                            te = nearest(tend, -1.0_dp)
                    end if
                    call rk_step(es, t, s, k1, h, k2, k3, k4, sn, stat, te)
                    ! a state past RK_DIVERGED (or NaN) has left the stability region:
                    ! stop before its rates overflow (a trapping build would abort)
                    if (stat%code == 0 .and. .not. maxval(abs(sn(1:m))) < RK_DIVERGED) &
                        call set_status(stat, ERR_NUMERIC, 'rk4', 'the state diverged (beyond '// &
                                        fmt_real(RK_DIVERGED)//') at t = '//fmt_real(t + h)// &
                                        ' (dt = '//fmt_real(opts%dt)//' is beyond the stability limit?)')
                    if (stat%code == 0) call rk_rates(es, te, sn, k1n, stat, holdn)
                    stats%fevals = stats%fevals + 4
                    stats%steps = stats%steps + 1
                    if (stat%code /= 0) return
                    jev = 0
                    if (evon) call rk_first_event(es, s, sn, k1, k1n, hold, holdn, h, skipj, jev, &
                                                  kind, theta)
                    if (jev == 0) then
                        if (sens) then
                            call rk_sens_step(es, pars, t, s, k1, k2, k3, k4, h, sm, stat, mldl, te)
                            if (stat%code /= 0) return
                        end if
                        s = sn
                        k1 = k1n
                        hold = holdn
                        t = t + h
                        i = i + 1
                        nstall = 0
                        skipj = 0
                        if (hcap < opts%dt) then
                            ! past the unresolved start: equal steps of dt again
                            hcap = opts%dt
                            if (tend - t <= 1.0e-13_dp*max(1.0_dp, abs(t))) exit
                            nsub = ceiling((tend - t)/opts%dt*(1.0_dp - 1.0e-12_dp))
                            i = 0
                        end if
                        cycle
                    end if
                    ! redo the step to the event, switch there
                    hs = theta*h
                    if (hs <= 1.0e-14_dp*max(1.0_dp, abs(t)) .and. &
                        h > 1.0e-10_dp*max(1.0_dp, abs(t))) then
                        ! wrong way from the start along the step's cubic: the step may
                        ! be too long to resolve a push that a fast (axial) vibration
                        ! reverses within it (small friction coefficients). Retry with
                        ! a shorter step before believing it.
                        hcap = h/16.0_dp
                        stats%event_steps = stats%event_steps + 1
                        cycle
                    end if
                    ! no progress: a switch at the step start, or (below) a switch that
                    ! changes no mode; a plain step or a switch that changes one resets
                    if (hs <= 1.0e-14_dp*max(1.0_dp, abs(t))) nstall = nstall + 1
                    if (nstall > 4*es%npt + 4) then
                        call set_status(stat, ERR_NO_CONVERGENCE, 'rk4', 'friction switching of '// &
                                        'component '//fmt_int(jev)//' does not settle at t = '// &
                                        fmt_real(t)//' (kind '//fmt_int(kind)//', mode '// &
                                        fmt_int(es%fmode(jev))//'): is dt = '// &
                                        fmt_real(opts%dt)//' beyond the stability limit?')
                        return
                    end if
                    if (hs > 0.0_dp) then
                        call rk_step(es, t, s, k1, hs, k2, k3, k4, sn, stat)
                        if (sens) then
                            call rk_sens_step(es, pars, t, s, k1, k2, k3, k4, hs, sm, stat, mldl)
                            if (stat%code /= 0) return
                        end if
                        s = sn
                        stats%fevals = stats%fevals + 3
                        stats%event_steps = stats%event_steps + 1
                        t = t + hs
                        if (kind == EVENT_UNSTICK) then
                            call rk_rates(es, t, s, k1n, stat, hold)
                            stats%fevals = stats%fevals + 1
                        end if
                    end if
                    call rk_switch(es, s(1:m), t, hs, kind, jev, hold, nstall, skipj, hist, stats, &
                                   stat, pars, sm, fm, dtp)
                    if (stat%code /= 0) return
                    call rk_rates(es, t, s, k1, stat, hold)
                    stats%fevals = stats%fevals + 1
                    if (stat%code /= 0) return
                    if (tend - t <= 1.0e-13_dp*max(1.0_dp, abs(t))) exit
                    nsub = ceiling((tend - t)/opts%dt*(1.0_dp - 1.0e-12_dp))
                    i = 0
                end do
                if (.not. atbreak) exit seg
                ! at the breakpoint: the rates after it (k1 holds those before:
                ! the left limit), and the sensitivities' jump where a
                ! parameter moves it
                t = tend
                if (sens) fm = k1(1:m)
                call rk_rates(es, t, s, k1, stat, hold)
                stats%fevals = stats%fevals + 1
                if (stat%code /= 0) return
                if (sens) call sens_break(es, pars, bk(ib), fm, k1(1:m), sm)
                ib = ib + 1
                if (t_out(k) - t <= 1.0e-13_dp*max(1.0_dp, abs(t))) exit seg
            end do seg
            if (.not. all(ieee_is_finite(s))) then
                call set_status(stat, ERR_NUMERIC, 'rk4', 'the state became non-finite'// &
                                ' before t = '//fmt_real(t_out(k))//' (dt = '// &
                                fmt_real(opts%dt)//' is beyond the stability limit?)')
                return
            end if
            t = t_out(k)
            call record(es, s(1:m), s(m + 1:), k, hist)
            if (sens) dstates(:, k, :) = sm
            if (associated(opts%progress)) opts%progress(1) = t
        end do
    end subroutine run_rk4

    !> The RK4 switch jev of the given kind at t, the end of the partial step
    !! hs to it: a velocity that reached zero is zero, the friction modes
    !! change, the sensitivities jump (when pars are given). nstall, skipj:
    !! chatter control.
    subroutine rk_switch(es, s, t, hs, kind, jev, hold, nstall, skipj, hist, stats, stat, &
                         pars, sm, fm, dtp)
        type(dyn_system_t), intent(inout) :: es
        real(dp), intent(inout) :: s(:)
        real(dp), intent(in) :: t, hs
        integer, intent(in) :: kind, jev
        real(dp), intent(inout) :: hold(:)
        integer, intent(inout) :: nstall, skipj
        type(history_t), intent(inout) :: hist
        type(integ_stats_t), intent(inout) :: stats
        type(status_t), intent(inout) :: stat
        type(dyn_param_t), intent(in), optional :: pars(:)
        real(dp), intent(inout), optional :: sm(:, :), fm(:), dtp(:)
        integer :: nev0

        if (kind == EVENT_ZERO_VELOCITY) s(es%nc + dyn_fric_dof(es, jev)) = 0.0_dp
        if (present(pars)) then
            call sens_event_pre(es, pars, t, s, kind, jev, hold(jev), sm, fm, dtp, stat)
            if (stat%code /= 0) return
        end if
        nev0 = stats%events
        if (kind == EVENT_ZERO_VELOCITY) then
            call apply_switch(es, s, t, kind, 0, hold, hist, stats, stat)
        else
            call apply_switch(es, s, t, kind, jev, hold, hist, stats, stat)
        end if
        if (stat%code /= 0) return
        if (stats%events == nev0) then
            ! the velocity only touched zero: once is legitimate, again and
            ! again (roots ever closer together: a push that the vibration
            ! reverses at once, tiny mu) is chatter: the component keeps its
            ! mode over the next step and the sign change is handled once,
            ! at its start, after it
            if (hs > 1.0e-14_dp*max(1.0_dp, abs(t))) nstall = nstall + 1
            if (nstall >= 3) skipj = jev
        else if (hs > 1.0e-14_dp*max(1.0_dp, abs(t))) then
            nstall = 0
        end if
        if (present(pars)) then
            call sens_event_post(es, t, s, fm, dtp, sm, stat)
            if (stat%code /= 0) return
        end if
    end subroutine rk_switch

    !> The first friction event along the RK4 step of length h from s (rates
    !! k1, holding forces hold) to sn (k1n, holdn): component jev (0: none),
    !! its kind and where, the fraction theta of the step (a sliding
    !! velocity's root along the step's cubic Hermite interpolant, a sticking
    !! component's excess force linear in the step). skipj: a chattering
    !! component left out for this step.
    subroutine rk_first_event(es, s, sn, k1, k1n, hold, holdn, h, skipj, jev, kind, theta)
        type(dyn_system_t), intent(in) :: es
        real(dp), intent(in) :: s(:), sn(:), k1(:), k1n(:), hold(:), holdn(:), h
        integer, intent(in) :: skipj
        integer, intent(out) :: jev, kind
        real(dp), intent(out) :: theta
        real(dp) :: sr, cap, d3(3)
        integer :: j, kindj, n
        logical :: found

        n = es%nc
        jev = 0
        kind = 0
        theta = 2.0_dp
        do j = 1, 2*es%npt
            cap = es%fric((j + 1)/2)
            if (cap == 0.0_dp .or. j == skipj) cycle
            if (es%fmode(j) /= 0) then
                kindj = EVENT_ZERO_VELOCITY
                if (real(es%fmode(j), dp)*sn(n + dyn_fric_dof(es, j)) > 0.0_dp) cycle
                d3 = [sn(n + dyn_fric_dof(es, j)), h*k1(n + dyn_fric_dof(es, j)), &
                      h*k1n(n + dyn_fric_dof(es, j))]
                call first_root(kindj, es%fmode(j), cap, s(n + dyn_fric_dof(es, j)), d3, .true., &
                                sr, found)
                if (.not. found) sr = 1.0_dp
            else
                kindj = EVENT_UNSTICK
                if (abs(holdn(j)) <= cap) cycle
                ! |hold| - cap changes sign: linear in the step
                sr = (cap - abs(hold(j)))/(abs(holdn(j)) - abs(hold(j)))
                sr = max(0.0_dp, min(1.0_dp, sr))
            end if
            if (sr < theta) then
                theta = sr
                jev = j
                kind = kindj
            end if
        end do
    end subroutine rk_first_event

    !> Jacobians and mass matrix at the state y into `it`; allocates the
    !! work arrays of `it` on first use.
    subroutine radau_jacobian(sys, t, y, it, dy, power)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t          !< time of y (s)
        real(dp), intent(in) :: y(:)
        type(radau_t), intent(inout) :: it
        !> the M-form rates at y and their work rates, from the same assembly
        !! (constant mass matrix only: rates_m otherwise)
        real(dp), intent(out), optional :: dy(:), power(:)
        real(dp) :: torque
        type(status_t) :: nostat
        integer :: n, nb
        n = sys%nc
        nb = 2*sys%ckl + sys%cku + 1
        if (.not. allocated(it%mb)) then
            allocate (it%mb(nb, n), it%kb(nb, n), it%cb(nb, n), it%b(n), it%p(n), it%d(n), &
                      it%a1(nb, n), it%a2(nb, n), it%rhs(n), it%tmp(n), it%zrhs(n), &
                      it%s1(sys%ckl + 1, n), it%s2(sys%ckl + 1, n))
            it%lu1%n = n
            it%lu1%kl = sys%ckl
            it%lu1%ku = sys%cku
            it%lu2%n = n
            it%lu2%kl = sys%ckl
            it%lu2%ku = sys%cku
            allocate (it%lu1%ab(nb, n), it%lu2%ab(nb, n))
        end if
        ! a constant mass matrix is copied once (M0 = M(q) only with rotary inertia)
        it%rot = sys%rotary .and. .not. sys%modal
        if (it%rot) then
            ! M(q) = M_c + R(q): the rows of M_c once; M0 = M(qjac) for the
            ! iteration matrices is M_c plus the 2 x 2 slope blocks J a a^T
            ! of the masses (symmetric: the L D L^T path stays open)
            if (.not. it%have_mass) then
                call band_to_rows(n, sys%ckl, sys%cku, sys%mb, it%m_start, it%m_col, it%m_val)
                it%m_sym = sys%ckl == sys%cku
                if (it%m_sym) it%m_sym = band_symmetric(n, sys%ckl, sys%mb)
            end if
            it%qjac = y(1:n)
            call dyn_mass(sys, it%qjac, it%mb)
        else if (sys%rotary .or. .not. it%have_mass) then
            call dyn_cmass(sys, y, it%mb)
            call band_to_rows(n, sys%ckl, sys%cku, it%mb, it%m_start, it%m_col, it%m_val)
            it%m_sym = sys%ckl == sys%cku
            if (it%m_sym) it%m_sym = band_symmetric(n, sys%ckl, it%mb)
        end if
        it%have_mass = .true.
        if (present(dy)) then
            if (sys%nx > 0) then
                call dyn_eval(sys, t, y, nostat, kb=it%kb, cb=it%cb, b=it%b, p=it%p, d=it%d, &
                              e=it%e, force=dy(n + 1:2*n), power=power, torque=torque, &
                              xrate=dy(2*n + 1))
            else
                call dyn_eval(sys, t, y, nostat, kb=it%kb, cb=it%cb, b=it%b, p=it%p, d=it%d, &
                              e=it%e, force=dy(n + 1:2*n), power=power, torque=torque)
            end if
            dy(1:n) = y(n + 1:2*n)
        else
            call dyn_eval(sys, t, y, nostat, kb=it%kb, cb=it%cb, b=it%b, p=it%p, d=it%d, e=it%e)
        end if
    end subroutine radau_jacobian

    !> The nonzeros of a band matrix (LAPACK general band storage) by rows.
    pure subroutine band_to_rows(n, kl, ku, ab, start, col, val)
        integer, intent(in) :: n, kl, ku
        real(dp), intent(in) :: ab(2*kl + ku + 1, n)
        integer, allocatable, intent(inout) :: start(:), col(:)
        real(dp), allocatable, intent(inout) :: val(:)
        integer :: i, j, nnz
        nnz = count(ab(kl + 1:, :) /= 0.0_dp)
        if (allocated(start)) deallocate (start, col, val)
        allocate (start(n + 1), col(nnz), val(nnz))
        nnz = 0
        do i = 1, n
            start(i) = nnz + 1
            do j = max(1, i - kl), min(n, i + ku)
                if (ab(kl + ku + 1 + i - j, j) == 0.0_dp) cycle
                nnz = nnz + 1
                col(nnz) = j
                val(nnz) = ab(kl + ku + 1 + i - j, j)
            end do
        end do
        start(n + 1) = nnz + 1
    end subroutine band_to_rows

    !> y = A x for a matrix stored by rows (band_to_rows).
    pure subroutine rows_mv(start, col, val, x, y)
        integer, intent(in) :: start(:), col(:)
        real(dp), intent(in) :: val(:), x(:)
        real(dp), intent(out) :: y(:)
        integer :: i, k
        real(dp) :: acc
        do i = 1, size(start) - 1
            acc = 0.0_dp
            do k = start(i), start(i + 1) - 1
                acc = acc + val(k)*x(col(k))
            end do
            y(i) = acc
        end do
    end subroutine rows_mv

    !> a1 = l1 M + C, a2 = l2 M + C, b1 = l1 a1 + K, b2 = l2 a2 + K on the
    !! band rows r0..nb (one pass over the three matrices).
    pure subroutine combine_band(r0, nb, n, l1, l2, m, c, k, a1, a2, b1, b2)
        integer, intent(in) :: r0, nb, n
        real(dp), intent(in) :: l1
        complex(dp), intent(in) :: l2
        real(dp), intent(in) :: m(nb, n), c(nb, n), k(nb, n)
        real(dp), intent(inout) :: a1(nb, n), b1(nb, n)
        complex(dp), intent(inout) :: a2(nb, n), b2(nb, n)
        integer :: i, j
        real(dp) :: x1, xr, xi, l2r, l2i
        l2r = l2%re
        l2i = l2%im
        do j = 1, n
            do i = r0, nb
                x1 = l1*m(i, j) + c(i, j)
                a1(i, j) = x1
                b1(i, j) = l1*x1 + k(i, j)
                xr = l2r*m(i, j) + c(i, j)
                xi = l2i*m(i, j)
                a2(i, j) = cmplx(xr, xi, dp)
                b2(i, j) = cmplx(l2r*xr - l2i*xi + k(i, j), l2r*xi + l2i*xr, dp)
            end do
        end do
    end subroutine combine_band

    !> As combine_band for symmetric M, C, K of half-bandwidth k: a1, a2 on
    !! the whole band, the iteration matrices l1 a1 + K and l2 a2 + K only on
    !! the lower half, into s1, s2 (s(1 + i - j, j) = A(i, j)).
    pure subroutine combine_sym(k, n, l1, l2, m, c, kk, a1, a2, s1, s2)
        integer, intent(in) :: k, n
        real(dp), intent(in) :: l1
        complex(dp), intent(in) :: l2
        real(dp), intent(in) :: m(3*k + 1, n), c(3*k + 1, n), kk(3*k + 1, n)
        real(dp), intent(inout) :: a1(3*k + 1, n), s1(k + 1, n)
        complex(dp), intent(inout) :: a2(3*k + 1, n), s2(k + 1, n)
        integer :: i, j
        real(dp) :: x1, xr, xi, l2r, l2i
        l2r = l2%re
        l2i = l2%im
        do j = 1, n
            do i = k + 1, 2*k
                a1(i, j) = l1*m(i, j) + c(i, j)
                a2(i, j) = cmplx(l2r*m(i, j) + c(i, j), l2i*m(i, j), dp)
            end do
            do i = 2*k + 1, 3*k + 1
                x1 = l1*m(i, j) + c(i, j)
                a1(i, j) = x1
                s1(i - 2*k, j) = l1*x1 + kk(i, j)
                xr = l2r*m(i, j) + c(i, j)
                xi = l2i*m(i, j)
                a2(i, j) = cmplx(xr, xi, dp)
                s2(i - 2*k, j) = cmplx(l2r*xr - l2i*xi + kk(i, j), l2r*xi + l2i*xr, dp)
            end do
        end do
    end subroutine combine_sym

    !> Assemble and factor (lam^2 M + lam C + K - b w^T) for lam = gamma/h
    !! (real) and mu/h (complex), and keep lam M + C for the right sides.
    subroutine radau_factor(sys, it, h, gam, mu, stat)
        type(dyn_system_t), intent(in) :: sys
        type(radau_t), intent(inout) :: it
        real(dp), intent(in) :: h, gam
        complex(dp), intent(in) :: mu
        type(status_t), intent(inout) :: stat
        real(dp) :: l1
        complex(dp) :: l2
        integer :: i, j, kl, ku, r
        kl = sys%ckl
        ku = sys%cku
        l1 = gam/h
        l2 = mu/h
        it%h = h
        it%nlr = 0
        ! L D L^T when both matrices are symmetric and their pivots are safe:
        ! real pivots positive (the matrix is then positive definite), complex
        ! pivots with a positive imaginary part (mu^2/h^2 M + mu/h C has one
        ! when C is semi-definite, and Schur complements keep it), which bounds
        ! the growth without pivoting. Anything else: LU with partial pivoting.
        ! Symmetry: without Kelvin-Voigt damping, motor and rotary inertia, K is the
        ! tangent of the strain energy and the hinge springs and C holds the
        ! friction and drag of the masses on its diagonal: symmetric by
        ! construction. Otherwise they are checked.
        it%sym = sys%nx == 0 .and. kl == ku .and. it%m_sym
        if (it%sym .and. (sys%eta /= 0.0_dp .or. sys%motor /= 0.0_dp .or. sys%rotary)) then
            it%sym = band_symmetric(sys%nc, kl, it%kb)
            if (it%sym) it%sym = band_symmetric(sys%nc, kl, it%cb)
            ! the gyroscopic terms of the rotary inertia (Eq. 132), the motor's
            ! torque on the tip slopes and Kelvin-Voigt's dD/dq v are not
            ! symmetric but small against l^2 M + l C + K: the simplified
            ! Newton iteration takes the symmetric parts (its residuals are
            ! exact, so the converged stages are the same) and keeps L D L^T
            if (.not. it%sym) it%sym = nearly_symmetric(sys%nc, kl, l1, it%mb, it%cb, it%kb)
            ! larger but confined to a few rows (rotary inertia whose gyroscopic
            ! terms grow with the slope rates): the lower half by L D L^T and
            ! the rest as an exact low-rank correction of the solves
            if (.not. it%sym) it%sym = skew_rows(sys%nc, kl, l1, l2, it%cb, it%kb, it)
        end if
        if (it%sym) then
            call combine_sym(kl, sys%nc, l1, l2, it%mb, it%cb, it%kb, it%a1, it%a2, &
                             it%s1, it%s2)
            do i = 1, it%nst
                call pin_sym(sys%nc, kl, it%s1, it%s2, it%stuck(i))
            end do
            call ldlt_real(sys%nc, kl, it%s1, it%sym)
            if (it%sym) call ldlt_cplx(sys%nc, kl, it%s2, it%sym)
            if (it%sym .and. it%nlr > 0) call lr_setup(sys%nc, kl, it, it%sym)
            if (it%sym) return
            it%nlr = 0
        end if
        ! rows 1..kl of band storage are the factorization's fill-in: skip them
        r = kl + 1
        call combine_band(r, size(it%mb, 1), sys%nc, l1, l2, it%mb, it%cb, it%kb, &
                          it%a1, it%a2, it%lu1%ab, it%lu2%ab)
        if (sys%nx > 0) then
            do j = 1, sys%nc
                if (it%p(j) == 0.0_dp .and. it%d(j) == 0.0_dp) cycle
                do i = max(1, j - ku), min(sys%nc, j + kl)
                    if (it%b(i) == 0.0_dp) cycle
                    r = kl + ku + 1 + i - j
                    it%lu1%ab(r, j) = it%lu1%ab(r, j) &
                        - it%b(i)*(it%p(j) + l1*it%d(j))/(l1 - it%e)
                    it%lu2%ab(r, j) = it%lu2%ab(r, j) &
                        - it%b(i)*(it%p(j) + l2*it%d(j))/(l2 - it%e)
                end do
            end do
        end if
        do i = 1, it%nst
            call pin_band(sys%nc, kl, ku, it%lu1%ab, it%lu2%ab, it%stuck(i))
        end do
        call band_factor(it%lu1, stat)
        if (stat%code /= 0) return
        call zband_factor(it%lu2, stat)
    end subroutine radau_factor

    !> Symmetrize K and C (in place) when their skew parts are small against
    !! the real iteration matrix l^2 M + l C + K: every skew entry below 1e-3
    !! of the smallest diagonal entry. False (nothing changed) otherwise.
    function nearly_symmetric(n, k, l, m, c, kk) result(ok)
        integer, intent(in) :: n, k
        real(dp), intent(in) :: l, m(3*k + 1, n)
        real(dp), intent(inout) :: c(3*k + 1, n), kk(3*k + 1, n)
        logical :: ok
        real(dp) :: dmin, skew, a, b
        integer :: i, j
        ok = .false.
        dmin = huge(1.0_dp)
        do j = 1, n
            dmin = min(dmin, l*l*m(2*k + 1, j) + l*c(2*k + 1, j) + kk(2*k + 1, j))
        end do
        if (.not. (dmin > 0.0_dp)) return
        skew = 0.0_dp
        do j = 1, n
            do i = j + 1, min(n, j + k)
                skew = max(skew, abs(l*(c(2*k + 1 + i - j, j) - c(2*k + 1 + j - i, i)) &
                                     + kk(2*k + 1 + i - j, j) - kk(2*k + 1 + j - i, i)))
            end do
        end do
        if (skew > 1.0e-3_dp*dmin) return
        do j = 1, n
            do i = j + 1, min(n, j + k)
                a = 0.5_dp*(c(2*k + 1 + i - j, j) + c(2*k + 1 + j - i, i))
                b = 0.5_dp*(kk(2*k + 1 + i - j, j) + kk(2*k + 1 + j - i, i))
                c(2*k + 1 + i - j, j) = a
                c(2*k + 1 + j - i, i) = a
                kk(2*k + 1 + i - j, j) = b
                kk(2*k + 1 + j - i, i) = b
            end do
        end do
        ok = .true.
    end function nearly_symmetric

    !> The entries where K or C (band storage, half-bandwidth k) differ from
    !! their transposes (beyond band_symmetric's round-off), found in the
    !! upper half: their rows R and the differences l (C(i, j) - C(j, i)) +
    !! K(i, j) - K(j, i) of the real (l1) and complex (l2) iteration matrix,
    !! into it. False when more than LR_MAX rows or LE_MAX entries differ.
    !! Rows and columns of sticking components are pinned: not counted.
    function skew_rows(n, k, l1, l2, c, kk, it) result(ok)
        integer, intent(in) :: n, k
        real(dp), intent(in) :: l1, c(3*k + 1, n), kk(3*k + 1, n)
        complex(dp), intent(in) :: l2
        type(radau_t), intent(inout) :: it
        logical :: ok
        real(dp) :: tolc, tolk, dc, dk
        integer :: i, j, pos
        ok = .false.
        if (.not. allocated(it%lr_row)) then
            allocate (it%lr_row(LR_MAX), it%le_k(LE_MAX), it%le_col(LE_MAX), &
                      it%le_d1(LE_MAX), it%le_d2(LE_MAX))
        end if
        tolc = 1.0e-12_dp*maxval(abs(c(2*k + 1, :)))
        tolk = 1.0e-12_dp*maxval(abs(kk(2*k + 1, :)))
        it%nlr = 0
        it%nle = 0
        do j = 1, n
            do i = max(1, j - k), j - 1
                dc = c(2*k + 1 + i - j, j) - c(2*k + 1 + j - i, i)
                dk = kk(2*k + 1 + i - j, j) - kk(2*k + 1 + j - i, i)
                if (abs(dc) <= tolc .and. abs(dk) <= tolk) cycle
                if (it%nst > 0) then
                    if (any(it%stuck(1:it%nst) == i) .or. any(it%stuck(1:it%nst) == j)) cycle
                end if
                pos = findloc(it%lr_row(1:it%nlr), i, 1)
                if (pos == 0 .and. it%nlr == LR_MAX .or. it%nle == LE_MAX) then
                    it%nlr = 0
                    return
                end if
                if (pos == 0) then
                    it%nlr = it%nlr + 1
                    it%lr_row(it%nlr) = i
                    pos = it%nlr
                end if
                it%nle = it%nle + 1
                it%le_k(it%nle) = pos
                it%le_col(it%nle) = j
                it%le_d1(it%nle) = l1*dc + dk
                it%le_d2(it%nle) = l2*dc + dk
            end do
        end do
        ok = .true.
    end function skew_rows

    !> After the L D L^T of the lower halves: W = A_L^-1 E_R and the
    !! capacitance matrices (I + D W)^-1 of the real and complex iteration
    !! matrices (Sherman-Morrison-Woodbury). ok false when one is singular.
    subroutine lr_setup(n, k, it, ok)
        integer, intent(in) :: n, k
        type(radau_t), intent(inout) :: it
        logical, intent(out) :: ok
        integer :: m, e, r
        r = it%nlr
        if (.not. allocated(it%lr_w1)) then
            allocate (it%lr_w1(n, LR_MAX), it%lr_w2(n, LR_MAX), it%lr_c1(LR_MAX, LR_MAX), &
                      it%lr_c2(LR_MAX, LR_MAX))
        end if
        do m = 1, r
            it%lr_w1(:, m) = 0.0_dp
            it%lr_w1(it%lr_row(m), m) = 1.0_dp
            call ldlt_solve_real(n, k, it%s1, it%lr_w1(:, m))
            it%lr_w2(:, m) = (0.0_dp, 0.0_dp)
            it%lr_w2(it%lr_row(m), m) = (1.0_dp, 0.0_dp)
            call ldlt_solve_cplx(n, k, it%s2, it%lr_w2(:, m))
        end do
        it%lr_c1(1:r, 1:r) = (0.0_dp, 0.0_dp)
        it%lr_c2(1:r, 1:r) = (0.0_dp, 0.0_dp)
        do m = 1, r
            it%lr_c1(m, m) = (1.0_dp, 0.0_dp)
            it%lr_c2(m, m) = (1.0_dp, 0.0_dp)
        end do
        do e = 1, it%nle
            m = it%le_k(e)
            it%lr_c1(m, 1:r) = it%lr_c1(m, 1:r) + it%le_d1(e)*it%lr_w1(it%le_col(e), 1:r)
            it%lr_c2(m, 1:r) = it%lr_c2(m, 1:r) + it%le_d2(e)*it%lr_w2(it%le_col(e), 1:r)
        end do
        call small_inverse(r, it%lr_c1, ok)
        if (ok) call small_inverse(r, it%lr_c2, ok)
        ! a large inverse: A_L is nearly singular where A is not (skew parts
        ! as large as the symmetric ones); the correction would lose digits
        if (ok) ok = maxval(abs(it%lr_c1(1:r, 1:r))) < LR_COND .and. &
                     maxval(abs(it%lr_c2(1:r, 1:r))) < LR_COND
    end subroutine lr_setup

    !> a(1:r, 1:r) replaced by its inverse (Gauss-Jordan with partial
    !! pivoting; r is a handful). ok false for a zero or non-finite pivot.
    pure subroutine small_inverse(r, a, ok)
        integer, intent(in) :: r
        complex(dp), intent(inout) :: a(:, :)
        logical, intent(out) :: ok
        complex(dp) :: b(r, 2*r), row(2*r)
        integer :: i, p
        b = (0.0_dp, 0.0_dp)
        b(:, 1:r) = a(1:r, 1:r)
        do i = 1, r
            b(i, r + i) = (1.0_dp, 0.0_dp)
        end do
        ok = .false.
        do i = 1, r
            p = i - 1 + maxloc(abs(b(i:r, i)), 1)
            if (.not. (abs(b(p, i)) > 0.0_dp .and. abs(b(p, i)) < huge(1.0_dp))) return
            row = b(p, :)
            b(p, :) = b(i, :)
            b(i, :) = row/row(i)
            do p = 1, r
                if (p /= i) b(p, :) = b(p, :) - b(p, i)*b(i, :)
            end do
        end do
        a(1:r, 1:r) = b(:, r + 1:)
        ok = .true.
    end subroutine small_inverse

    !> x = A_L^-1 b on entry, A^-1 b on exit (real iteration matrix):
    !! x - W (I + D W)^-1 D x.
    pure subroutine lr_real(it, x)
        type(radau_t), intent(in) :: it
        real(dp), intent(inout) :: x(:)
        real(dp) :: t(it%nlr)
        integer :: e, r
        r = it%nlr
        t = 0.0_dp
        do e = 1, it%nle
            t(it%le_k(e)) = t(it%le_k(e)) + it%le_d1(e)*x(it%le_col(e))
        end do
        t = real(matmul(it%lr_c1(1:r, 1:r), t), dp)
        x = x - matmul(it%lr_w1(:, 1:r), t)
    end subroutine lr_real

    !> lr_real for the complex iteration matrix.
    pure subroutine lr_cplx(it, x)
        type(radau_t), intent(in) :: it
        complex(dp), intent(inout) :: x(:)
        complex(dp) :: t(it%nlr)
        integer :: e, r
        r = it%nlr
        t = (0.0_dp, 0.0_dp)
        do e = 1, it%nle
            t(it%le_k(e)) = t(it%le_k(e)) + it%le_d2(e)*x(it%le_col(e))
        end do
        t = matmul(it%lr_c2(1:r, 1:r), t)
        x = x - matmul(it%lr_w2(:, 1:r), t)
    end subroutine lr_cplx

    !> Pin unknown i (a sticking friction component) in the symmetric
    !! iteration matrices: row and column i zero, diagonal 1 (complex: 1 + i,
    !! whose positive imaginary part the L D L^T test asks for).
    pure subroutine pin_sym(n, k, s1, s2, i)
        integer, intent(in) :: n, k, i
        real(dp), intent(inout) :: s1(k + 1, n)
        complex(dp), intent(inout) :: s2(k + 1, n)
        integer :: j
        s1(:, i) = 0.0_dp
        s2(:, i) = (0.0_dp, 0.0_dp)
        do j = max(1, i - k), i - 1
            s1(1 + i - j, j) = 0.0_dp
            s2(1 + i - j, j) = (0.0_dp, 0.0_dp)
        end do
        s1(1, i) = 1.0_dp
        s2(1, i) = (1.0_dp, 1.0_dp)
    end subroutine pin_sym

    !> pin_sym for the general band storage of the LU path.
    pure subroutine pin_band(n, kl, ku, a1, a2, i)
        integer, intent(in) :: n, kl, ku, i
        real(dp), intent(inout) :: a1(2*kl + ku + 1, n)
        complex(dp), intent(inout) :: a2(2*kl + ku + 1, n)
        integer :: c
        a1(kl + 1:, i) = 0.0_dp
        a2(kl + 1:, i) = (0.0_dp, 0.0_dp)
        do c = max(1, i - kl), min(n, i + ku)
            a1(kl + ku + 1 + i - c, c) = 0.0_dp
            a2(kl + ku + 1 + i - c, c) = (0.0_dp, 0.0_dp)
        end do
        a1(kl + ku + 1, i) = 1.0_dp
        a2(kl + ku + 1, i) = (1.0_dp, 1.0_dp)
    end subroutine pin_band

    !> A band matrix (general band storage, kl = ku) is symmetric to
    !! round-off (the tangent is symmetric up to the order of its products).
    !! The iteration matrices are formed entry by entry from M, C and K, so
    !! they are symmetric when these three are; L D L^T reads the lower half.
    pure logical function band_symmetric(n, k, ab) result(sym)
        integer, intent(in) :: n, k
        real(dp), intent(in) :: ab(3*k + 1, n)
        integer :: i, j
        real(dp) :: tol
        ! scale: the largest diagonal entry (M, K and C of a structure peak there)
        tol = 1.0e-12_dp*maxval(abs(ab(2*k + 1, :)))
        sym = .true.
        do j = 1, n
            do i = j + 1, min(n, j + k)
                if (abs(ab(2*k + 1 + i - j, j) - ab(2*k + 1 + j - i, i)) > tol) then
                    sym = .false.
                    return
                end if
            end do
        end do
    end function band_symmetric

    !> Solve (lam - J) [x; y; z] = [r; s; t] with the real factorization
    !! (lam = gamma/h). On entry w = [r; M s; t] (the velocity row already
    !! multiplied by the step-start mass matrix M0: the "M-form" of the
    !! residual, which needs no M^-1); on exit w = [x; y; z].
    subroutine solve_real(sys, it, lam, w, r_zero)
        type(dyn_system_t), intent(in) :: sys
        type(radau_t), intent(inout) :: it
        real(dp), intent(in) :: lam
        real(dp), intent(inout) :: w(:)
        !> the displacement rows r are zero: skip the products with them
        logical, intent(in), optional :: r_zero
        real(dp) :: zt
        integer :: n
        logical :: skip
        associate (rhs => it%rhs, ab => it%a1, s => it%s1, lu => it%lu1)
            include 'beamid_radau_solve.inc'
        end associate
    end subroutine solve_real

    !> Complex counterpart of solve_real (lam = mu/h), same M-form input.
    subroutine solve_cplx(sys, it, lam, w, r_zero)
        type(dyn_system_t), intent(in) :: sys
        type(radau_t), intent(inout) :: it
        complex(dp), intent(in) :: lam
        complex(dp), intent(inout) :: w(:)
        logical, intent(in), optional :: r_zero   !< as in solve_real
        complex(dp) :: zt
        integer :: n
        logical :: skip
        associate (rhs => it%zrhs, ab => it%a2, s => it%s2, lu => it%lu2)
            include 'beamid_radau_solve.inc'
        end associate
    end subroutine solve_cplx

    !> Rates of y in M-form: (v, M0 M(q)^-1 F, x'). With a constant mass
    !! matrix M0 M^-1 F = F and no solve is needed (the cost of a rate is one
    !! internal force); so with rotary inertia in the full model, whose
    !! residuals are written F - M(q) a (to_mform at the stage's q): rates_m
    !! then returns F. In modal coordinates with rotary inertia M(q) is
    !! factored at y.
    subroutine rates_m(sys, t, it, y, dy, power, stat)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t          !< time of y (s)
        type(radau_t), intent(inout) :: it
        real(dp), intent(in) :: y(:)
        real(dp), intent(out) :: dy(:), power(:)
        type(status_t), intent(inout) :: stat
        integer :: n
        n = sys%nc
        if (sys%rotary .and. .not. it%rot) then
            call dyn_eval(sys, t, y, stat, rates=dy, power=power)
            it%tmp = dy(n + 1:2*n)
            call rows_mv(it%m_start, it%m_col, it%m_val, it%tmp, dy(n + 1:2*n))
        else
            if (sys%nx > 0) then
                call dyn_eval(sys, t, y, stat, force=dy(n + 1:2*n), power=power, &
                              xrate=dy(2*n + 1))
            else
                call dyn_eval(sys, t, y, stat, force=dy(n + 1:2*n), power=power)
            end if
            dy(1:n) = y(n + 1:2*n)
        end if
    end subroutine rates_m

    !> Put a rate-form vector into M-form: x(n+1:2n) <- M0 x(n+1:2n), or
    !! M(q) x(n+1:2n) = M_c x + R(q) x with rotary inertia (q: the stage's
    !! displacements; default the Jacobian's, i.e. M0).
    subroutine to_mform(sys, it, x, q)
        type(dyn_system_t), intent(in) :: sys
        type(radau_t), intent(inout) :: it
        real(dp), intent(inout) :: x(:)
        real(dp), intent(in), optional :: q(:)
        integer :: n
        n = sys%nc
        it%tmp = x(n + 1:2*n)
        call rows_mv(it%m_start, it%m_col, it%m_val, it%tmp, x(n + 1:2*n))
        if (it%rot) then
            if (present(q)) then
                call dyn_rot_mv(sys, q, it%tmp, x(n + 1:2*n))
            else
                call dyn_rot_mv(sys, it%qjac, it%tmp, x(n + 1:2*n))
            end if
        end if
    end subroutine to_mform

    !> Mean square of x weighted by the inverse error scales iscal.
    pure real(dp) function wrms(x, iscal)
        real(dp), intent(in) :: x(:), iscal(:)
        integer :: i
        wrms = 0.0_dp
        do i = 1, size(x)
            wrms = wrms + (x(i)*iscal(i))**2
        end do
        wrms = wrms/real(size(x), dp)
    end function wrms

    !> Lagrange basis on the nodes (0, c1, c2, 1), the 0 node left out: the
    !! collocation polynomial through the stage increments is sum_j z_j l_j(s).
    pure function lagrange(s) result(l)
        real(dp), intent(in) :: s
        real(dp) :: l(3)
        real(dp), parameter :: nodes(4) = [0.0_dp, C1, C2, 1.0_dp]
        integer :: j, m
        do j = 1, 3
            l(j) = 1.0_dp
            do m = 1, 4
                if (m == j + 1) cycle
                l(j) = l(j)*(s - nodes(m))/(nodes(j + 1) - nodes(m))
            end do
        end do
    end function lagrange

    !> The sticking friction components of es into it (free indices and
    !! component numbers).
    subroutine set_stuck(es, it)
        type(dyn_system_t), intent(in) :: es
        type(radau_t), intent(inout) :: it
        integer :: j
        it%nst = 0
        do j = 1, size(es%fmode)
            if (es%fric((j + 1)/2) == 0.0_dp .or. es%fmode(j) /= 0) cycle
            it%nst = it%nst + 1
            it%stuck(it%nst) = dyn_fric_dof(es, j)
            it%stuckc(it%nst) = j
        end do
    end subroutine set_stuck

    !> The earliest friction event along an accepted Radau step: the
    !! collocation polynomial of each sliding component's velocity (stage
    !! increments z), and of each sticking component's constraint force
    !! (hold0 at the start, hst at the stages). jev = 0: none; else the
    !! component, its kind and the root sev in [0, 1] (fraction of the step).
    subroutine radau_events(es, y, z, hold0, hst, jev, kev, sev)
        type(dyn_system_t), intent(in) :: es
        real(dp), intent(in) :: y(:), z(:, :), hold0(:), hst(:, :)
        integer, intent(out) :: jev, kev
        real(dp), intent(out) :: sev
        integer :: j, i, n, md
        real(dp) :: cap, sr, p3(3)
        logical :: found
        n = es%nc
        jev = 0
        kev = 0
        sev = 2.0_dp
        do j = 1, size(es%fmode)
            cap = es%fric((j + 1)/2)
            if (cap == 0.0_dp) cycle
            md = es%fmode(j)
            if (md /= 0) then
                i = n + dyn_fric_dof(es, j)
                p3 = z(i, :)
                if (all(real(md, dp)*(y(i) + p3) > 0.0_dp) .and. real(md, dp)*y(i) > 0.0_dp) cycle
                call first_root(EVENT_ZERO_VELOCITY, md, cap, y(i), p3, .false., sr, found)
                if (.not. found) cycle
                if (sr < sev) then
                    sev = sr
                    jev = j
                    kev = EVENT_ZERO_VELOCITY
                end if
            else
                if (all(abs(hst(j, :)) <= cap)) cycle
                p3 = hst(j, :) - hold0(j)
                call first_root(EVENT_UNSTICK, 0, cap, hold0(j), p3, .false., sr, found)
                if (.not. found) cycle
                if (sr < sev) then
                    sev = sr
                    jev = j
                    kev = EVENT_UNSTICK
                end if
            end if
        end do
    end subroutine radau_events

    !> Is the switching function of component j (kind kev) at the end of
    !! the step small against its change over the step (a root at the end)?
    logical function near_root(es, y, z, hold0, hst, j, kev)
        type(dyn_system_t), intent(in) :: es
        real(dp), intent(in) :: y(:), z(:, :), hold0(:), hst(:, :)
        integer, intent(in) :: j, kev
        real(dp), parameter :: FRAC = 1.0e-6_dp
        integer :: i
        real(dp) :: g1, dg
        if (kev == EVENT_ZERO_VELOCITY) then
            i = es%nc + dyn_fric_dof(es, j)
            g1 = real(es%fmode(j), dp)*(y(i) + z(i, 3))
            dg = maxval(abs(z(i, :)))
        else
            g1 = es%fric((j + 1)/2) - abs(hst(j, 3))
            dg = maxval(abs(hst(j, :) - hold0(j)))
        end if
        near_root = g1 <= FRAC*dg
    end function near_root

    !> Radau IIA (order 5) with simplified Newton and step-size control.
    !!
    !! Cost per step (constant mass matrix): one Jacobian and the two
    !! factorizations, about two simplified-Newton iterations of three internal
    !! forces each (residuals in M-form, no M^-1), one more force for the
    !! error estimate. Three choices set the cost at a given accuracy
    !! (measured in docs/theory_dynamics.md):
    !! - the Jacobian is taken at the predicted second stage y + z2, not at
    !!   the step start: the stages lie around it, and the Newton contraction
    !!   falls from ~0.1 to ~0.03 at the steps this problem takes;
    !! - Newton stops only when the estimated remaining error is below
    !!   NEWTON_TOL (1 %) of the tolerance, and never after one iteration: the
    !!   error a simplified Newton leaves is systematic, it adds up over the
    !!   steps instead of averaging out;
    !! - a fresh Jacobian every step: the error estimate filters the stiff
    !!   (axial) components through (gamma/h - J)^-1, and a stale J lets them
    !!   through (four times the steps).
    !! The step size follows the standard controller on the order-4 estimate
    !! (Hairer-Wanner IV.8, Eq. 8.19-8.21).
    subroutine run_radau(sys, y0, t_out, opts, hist, stats, stat, pars, sm, dstates)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: y0(:), t_out(:)
        type(integ_opts_t), intent(in) :: opts
        type(history_t), intent(inout) :: hist
        type(integ_stats_t), intent(inout) :: stats
        type(status_t), intent(inout) :: stat
        !> forward sensitivities (as in run_rk4)
        type(dyn_param_t), intent(in), optional :: pars(:)
        real(dp), intent(inout), optional :: sm(:, :)
        real(dp), intent(inout), optional :: dstates(:, :, :)
        type(radau_run_t) :: r
        integer :: kout
        logical :: converged, redo, brk
        real(dp) :: tnext

        call radau_start(r, sys, y0, opts, hist, stats, stat, pars)
        if (stat%code /= 0) return
        r%bk = dyn_breakpoints(r%es, 0.0_dp, t_out(size(t_out)))
        kout = 1
        do while (kout <= size(t_out))
            if (t_out(kout) - r%t <= 1.0e-13_dp*max(1.0_dp, abs(r%t))) then
                call record(r%es, r%y, r%work, kout, hist)
                if (r%sens) dstates(:, kout, :) = sm
                if (associated(opts%progress)) opts%progress(1) = t_out(kout)
                kout = kout + 1
                cycle
            end if
            if (stats%steps + stats%rejected >= opts%max_steps) then
                call set_status(stat, ERR_NO_CONVERGENCE, RADAU_WHERE, 'step limit '// &
                                fmt_int(opts%max_steps)//' reached at t = '//fmt_real(r%t))
                return
            end if
            ! the next stop: the output time or a breakpoint before it
            do while (r%ib <= size(r%bk))
                if (r%bk(r%ib) > r%t + 1.0e-13_dp*max(1.0_dp, abs(r%t))) exit
                r%ib = r%ib + 1
            end do
            tnext = t_out(kout)
            brk = .false.
            if (r%ib <= size(r%bk)) then
                if (r%bk(r%ib) <= tnext + 1.0e-13_dp*max(1.0_dp, abs(tnext))) then
                    tnext = r%bk(r%ib)
                    brk = .true.
                end if
            end if
            call radau_predict(r, tnext, opts, stats, stat, brk)
            if (stat%code /= 0) return
            call radau_newton(r, stats, converged)
            if (.not. converged) then
                if (ieee_is_finite(r%dnorm) .and. r%theta > 0.0_dp .and. r%theta < 0.99_dp) then
                    call radau_reject(r, stats, 0.5_dp*r%hh)
                else
                    call radau_reject(r, stats, 0.25_dp*r%hh)
                end if
                cycle
            end if
            call radau_error(r, stats, stat)
            if (stat%code /= 0) return
            if (.not. r%err < 1.0_dp) then
                if (r%first) then
                    call radau_reject(r, stats, 0.1_dp*r%hh)
                else
                    call radau_reject(r, stats, r%hnew)
                end if
                cycle
            end if
            call radau_locate(r, hist, stats, stat, redo, pars, sm)
            if (stat%code /= 0) return
            if (redo) cycle
            call radau_accept(r, opts, stats, stat, pars, sm)
            if (stat%code /= 0) return
            if (r%jev /= 0) then
                ! the switch at the step's end
                call radau_switch(r, hist, stats, stat, .true., pars, sm)
                if (stat%code /= 0) return
                if (r%pend /= 0) r%h = max(r%h, r%hcut)
                r%pend = 0
            end if
        end do
    end subroutine run_radau

    !> run_radau's start: the tableau, the work arrays, the friction modes at
    !! the release and the step controller's first values (else the type's defaults).
    subroutine radau_start(r, sys, y0, opts, hist, stats, stat, pars)
        type(radau_run_t), intent(out) :: r
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: y0(:)
        type(integ_opts_t), intent(in) :: opts
        type(history_t), intent(inout) :: hist
        type(integ_stats_t), intent(inout) :: stats
        type(status_t), intent(inout) :: stat
        type(dyn_param_t), intent(in), optional :: pars(:)
        complex(dp) :: tm(3, 3), ti(3, 3)
        integer :: nn, n, i, nfc

        call radau_tableau(r%a, r%dmat, r%gam, r%mu, tm, ti)
        r%ti1 = real(ti(1, :), dp)
        r%ti2 = ti(2, :)
        r%tr = real(tm(:, 1), dp)
        r%tc = 2.0_dp*tm(:, 2)
        nn = sys%ncstate
        n = sys%nc
        r%n = n
        allocate (r%y(nn), r%z(nn, 3), r%zprev(nn, 3), r%fz(nn, 3), r%zd(nn, 3), r%f0(nn), &
                  r%f3(nn), r%e0(nn), r%ev(nn), r%iscal(nn), r%w1(nn), r%dz(nn, 3), &
                  r%work(sys%nwork), r%pw(sys%nwork, 3), r%w2(nn), r%ytmp(nn), r%ys(nn), stat=i)
        if (i /= 0) then
            call set_status(stat, ERR_INPUT, RADAU_WHERE, 'cannot allocate the work arrays of '// &
                            fmt_int(nn)//' states ('//fmt_real(8.0_dp*30.0_dp*real(nn, dp))// &
                            ' bytes)')
            return
        end if
        r%y = y0
        r%es = sys
        r%evon = events_on(r%es)
        r%es%events = r%evon
        r%sens = present(pars)
        r%hsp = 0.0_dp
        if (r%sens) allocate (r%fm(nn), r%dtp(size(pars)), r%dzp(nn, 3, size(pars)))
        r%rot_slow = r%es%rotary .and. r%es%modal
        nfc = 2*r%es%npt
        allocate (r%hold0(nfc), r%hst(nfc, 3), r%acc3(n), r%rv(n), r%it%stuck(nfc), &
                  r%it%stuckc(nfc))
        r%hold0 = 0.0_dp
        r%hst = 0.0_dp
        r%acc3 = 0.0_dp
        if (r%evon) then
            call start_modes(r%es, r%y, r%hold0, hist, stats, stat)
            if (stat%code /= 0) return
            call set_stuck(r%es, r%it)
        end if
        r%work = 0.0_dp
        r%h = opts%h0
        r%hprev = r%h
    end subroutine radau_start

    !> The next step: its length hh (cut at the output time tnext), the error
    !! weights, the stage predictor and, unless the last ones are kept, the
    !! Jacobian and both factorizations.
    subroutine radau_predict(r, tnext, opts, stats, stat, brk)
        type(radau_run_t), intent(inout) :: r
        real(dp), intent(in) :: tnext
        !> tnext is a breakpoint of the forcings (default no)
        logical, intent(in), optional :: brk
        type(integ_opts_t), intent(in) :: opts
        type(integ_stats_t), intent(inout) :: stats
        type(status_t), intent(inout) :: stat
        real(dp) :: lsc(3)
        integer :: i, j, n

        n = r%n
        r%hh = r%h
        r%clipped = .false.
        if (r%t + r%hh >= tnext - 1.0e-13_dp*max(1.0_dp, abs(r%t))) then
            r%hh = tnext - r%t
            r%clipped = .true.
        end if
        r%ts = r%t + CNODE*r%hh
        r%atbreak = .false.
        if (present(brk)) r%atbreak = brk .and. r%clipped
        if (r%atbreak) r%ts(3) = nearest(tnext, -1.0_dp)
        r%tiny_h = 1.0e-14_dp*max(1.0_dp, abs(r%t))
        if (r%hh < r%tiny_h) then
            call set_status(stat, ERR_NO_CONVERGENCE, RADAU_WHERE, 'step size '// &
                            fmt_real(r%hh)//' underflow at t = '//fmt_real(r%t))
            return
        end if
        ! error weights: displacements as given; velocity errors are measured as
        ! the displacement they cause over the step (err_v * h), so modes far
        ! beyond the accuracy of interest (axial, 1e3-1e5 rad/s) are damped
        ! by the L-stable scheme instead of being resolved.
        r%iscal = 1.0_dp/(opts%atol + opts%rtol*abs(r%y))
        r%iscal(n + 1:2*n) = r%iscal(n + 1:2*n)*r%hh
        ! starting values: the last collocation polynomial, extrapolated
        if (r%have_prev) then
            do i = 1, 3
                lsc = lagrange(1.0_dp + CNODE(i)*r%hh/r%hprev)
                r%z(:, i) = lsc(1)*r%zprev(:, 1) + lsc(2)*r%zprev(:, 2) &
                            + (lsc(3) - 1.0_dp)*r%zprev(:, 3)
            end do
        else
            r%z = 0.0_dp
        end if
        ! velocities consistent with the predicted displacements, so that the
        ! linear rows q' = v hold from the start: (D z_q)_i / h = v_n + z_v,i
        ! (the predicted displacements are as good as the velocities, and the
        ! solves then never need the product (lam M + C) r)
        do i = 1, 3
            r%z(n + 1:2*n, i) = (r%dmat(i, 1)*r%z(1:n, 1) + r%dmat(i, 2)*r%z(1:n, 2) &
                                 + r%dmat(i, 3)*r%z(1:n, 3))/r%hh - r%y(n + 1:2*n)
        end do
        ! sticking friction components stay where they are
        do j = 1, r%it%nst
            r%z(r%it%stuck(j), :) = 0.0_dp
            r%z(n + r%it%stuck(j), :) = 0.0_dp
        end do
        ! Jacobian at the predicted second stage, both factorizations
        ! (the assembly gives the stage-2 rates of the first iteration too)
        r%ys = r%y + r%z(:, 2)
        r%reused = r%may_reuse .and. r%hh == r%it%h
        if (.not. r%reused) then
            if (r%rot_slow) then
                call radau_jacobian(r%es, r%ts(2), r%ys, r%it)
            else
                call radau_jacobian(r%es, r%ts(2), r%ys, r%it, r%fz(:, 2), r%pw(:, 2))
            end if
            stats%jevals = stats%jevals + 1
            call radau_factor(r%es, r%it, r%hh, r%gam, r%mu, stat)
            if (stat%code /= 0) return
            stats%factorizations = stats%factorizations + 1
        end if
    end subroutine radau_predict

    !> The simplified Newton iteration on the decoupled stage systems; leaves
    !! the contraction rate in r%theta and the last correction's norm in r%dnorm.
    subroutine radau_newton(r, stats, converged)
        type(radau_run_t), intent(inout) :: r
        type(integ_stats_t), intent(inout) :: stats
        logical, intent(out) :: converged
        integer, parameter :: NIT = 7
        real(dp), parameter :: NEWTON_TOL = 1.0e-2_dp
        real(dp) :: dold
        type(status_t) :: inner
        integer :: newt, i, j, n

        n = r%n
        converged = .false.
        dold = 0.0_dp
        r%dnorm = 0.0_dp
        r%theta = 0.0_dp
        inner = status_t()
        do newt = 1, NIT
            ! residuals in M-form: G_i = f~(y + z_i) - [I; M0; 1] (D z)_i / h
            do i = 1, 3
                if (newt > 1 .or. i /= 2 .or. r%rot_slow .or. r%reused) then
                    r%ys = r%y + r%z(:, i)
                    call rates_m(r%es, r%ts(i), r%it, r%ys, r%fz(:, i), r%pw(:, i), &
                                 inner)
                    stats%fevals = stats%fevals + 1
                end if
                r%zd(:, i) = (r%dmat(i, 1)*r%z(:, 1) + r%dmat(i, 2)*r%z(:, 2) &
                              + r%dmat(i, 3)*r%z(:, 3))/r%hh
                if (r%it%rot) then
                    call to_mform(r%es, r%it, r%zd(:, i), r%y(1:n) + r%z(1:n, i))
                else
                    call to_mform(r%es, r%it, r%zd(:, i))
                end if
            end do
            if (inner%code /= 0) exit
            r%f3 = r%fz(:, 3)
            r%fz = r%fz - r%zd
            ! sticking components: the residual of their velocity row is
            ! minus the constraint force that holds them (M a - F); the
            ! rows are pinned
            do j = 1, r%it%nst
                r%hst(r%it%stuckc(j), :) = -r%fz(n + r%it%stuck(j), :)
                r%fz(r%it%stuck(j), :) = 0.0_dp
                r%fz(n + r%it%stuck(j), :) = 0.0_dp
            end do
            r%w1 = r%ti1(1)*r%fz(:, 1) + r%ti1(2)*r%fz(:, 2) + r%ti1(3)*r%fz(:, 3)
            r%w2 = r%ti2(1)*r%fz(:, 1) + r%ti2(2)*r%fz(:, 2) + r%ti2(3)*r%fz(:, 3)
            ! the rows q' = v of the stage system are linear and hold from the
            ! predictor on (and after every correction): their residual r is
            ! zero, and the solves skip the product (lam M + C) r
            call solve_real(r%es, r%it, r%gam/r%hh, r%w1, r_zero=.true.)
            call solve_cplx(r%es, r%it, r%mu/r%hh, r%w2, r_zero=.true.)
            do i = 1, 3
                r%dz(:, i) = r%tr(i)*r%w1 + real(r%tc(i)*r%w2, dp)
            end do
            r%dnorm = sqrt((wrms(r%dz(:, 1), r%iscal) + wrms(r%dz(:, 2), r%iscal) + &
                            wrms(r%dz(:, 3), r%iscal))/3.0_dp)
            if (.not. ieee_is_finite(r%dnorm)) exit
            r%z = r%z + r%dz
            stats%newton = stats%newton + 1
            if (newt > 1) then
                r%theta = r%dnorm/dold
                if (r%theta >= 0.99_dp) exit
                ! converged: the remaining error theta/(1 - theta) dnorm is small
                if (r%theta/(1.0_dp - r%theta)*r%dnorm <= NEWTON_TOL) then
                    converged = .true.
                    exit
                end if
                ! hopeless: it will not get there within NIT iterations
                if (r%theta**(NIT - newt)/(1.0_dp - r%theta)*r%dnorm > NEWTON_TOL) exit
            end if
            dold = max(r%dnorm, epsilon(1.0_dp))
        end do
    end subroutine radau_newton

    !> A rejected step: no reuse of the factors, no pending event, retry with
    !! the step hnext.
    subroutine radau_reject(r, stats, hnext)
        type(radau_run_t), intent(inout) :: r
        type(integ_stats_t), intent(inout) :: stats
        real(dp), intent(in) :: hnext

        r%may_reuse = .false.
        r%pend = 0
        stats%rejected = stats%rejected + 1
        r%reject = .true.
        r%h = hnext
    end subroutine radau_reject

    !> The error estimate (Hairer-Wanner IV.8, Eq. 8.19-8.20), in M-form, into
    !! r%err, and the step the controller proposes next, r%hnew.
    subroutine radau_error(r, stats, stat)
        type(radau_run_t), intent(inout) :: r
        type(integ_stats_t), intent(inout) :: stats
        type(status_t), intent(inout) :: stat
        real(dp), parameter :: SAFE = 0.8_dp, FACL = 5.0_dp, FACR = 0.125_dp
        real(dp) :: quot
        integer :: j, n

        n = r%n
        ! f0: the rates at the step start. After an accepted step they are the
        ! last iteration's third-stage rates, taken at y - dz3 (the last
        ! correction, below NEWTON_TOL of the tolerance): the estimate moves
        ! by at most that much through (gamma/h - J)^-1 J, and a force is saved.
        if (.not. r%have_f0) then
            if (r%it%rot) then
                ! the acceleration a at y (M(q) factored once), f0 = M(q) a
                call dyn_eval(r%es, r%t, r%y, stat, rates=r%f0, power=r%pw(:, 1))
                if (stat%code /= 0) return
                r%acc3 = r%f0(n + 1:2*n)
                call to_mform(r%es, r%it, r%f0, r%y(1:n))
            else
                call rates_m(r%es, r%t, r%it, r%y, r%f0, r%pw(:, 1), stat)
                if (stat%code /= 0) return
            end if
            stats%fevals = stats%fevals + 1
            r%have_f0 = .true.
        end if
        r%e0 = (DD(1)*r%z(:, 1) + DD(2)*r%z(:, 2) + DD(3)*r%z(:, 3))/r%hh
        call to_mform(r%es, r%it, r%e0)
        r%ev = r%f0 + r%e0
        if (r%it%rot) then
            ! f0 holds M(q_n) a_n; the M-form wants M0 a_n
            r%rv = 0.0_dp
            call dyn_rot_mv(r%es, r%it%qjac, r%acc3, r%rv)
            call dyn_rot_mv(r%es, r%y(1:n), -r%acc3, r%rv)
            r%ev(n + 1:2*n) = r%ev(n + 1:2*n) + r%rv
        end if
        do j = 1, r%it%nst
            r%ev(r%it%stuck(j)) = 0.0_dp
            r%ev(n + r%it%stuck(j)) = 0.0_dp
        end do
        call solve_real(r%es, r%it, r%gam/r%hh, r%ev)
        r%err = max(sqrt(wrms(r%ev, r%iscal)), 1.0e-10_dp)
        if (r%err >= 1.0_dp .and. (r%first .or. r%reject)) then
            r%ytmp = r%y + r%ev
            call rates_m(r%es, r%t, r%it, r%ytmp, r%ev, r%pw(:, 1), stat)
            if (stat%code /= 0) return
            r%ev = r%ev + r%e0
            do j = 1, r%it%nst
                r%ev(r%it%stuck(j)) = 0.0_dp
                r%ev(n + r%it%stuck(j)) = 0.0_dp
            end do
            call solve_real(r%es, r%it, r%gam/r%hh, r%ev)
            r%err = max(sqrt(wrms(r%ev, r%iscal)), 1.0e-10_dp)
            stats%fevals = stats%fevals + 1
        end if
        quot = max(FACR, min(FACL, r%err**0.25_dp/SAFE))
        r%hnew = r%hh/quot
    end subroutine radau_error

    !> Friction events on an accurate step: the first root of a sliding
    !! component's velocity or of a sticking one's excess force along the
    !! collocation polynomial. Inside the step: redo the step to end there
    !! (targeted; redo = .true.); at the end: r%jev /= 0, switch after
    !! accepting.
    subroutine radau_locate(r, hist, stats, stat, redo, pars, sm)
        type(radau_run_t), intent(inout) :: r
        type(history_t), intent(inout) :: hist
        type(integ_stats_t), intent(inout) :: stats
        type(status_t), intent(inout) :: stat
        logical, intent(out) :: redo
        type(dyn_param_t), intent(in), optional :: pars(:)
        real(dp), intent(inout), optional :: sm(:, :)
        logical :: at_end

        redo = .false.
        r%jev = 0
        if (r%evon) call radau_events(r%es, r%y, r%z, r%hold0, r%hst, r%jev, r%kev, r%sev)
        if (r%jev /= 0) then
            at_end = (1.0_dp - r%sev)*r%hh <= 1.0e-12_dp*max(1.0_dp, abs(r%t)) .or. &
                     (r%pend == r%jev .and. r%hh == r%hpend .and. r%sev >= 0.5_dp)
            if (at_end) return
            redo = .true.
            stats%event_steps = stats%event_steps + 1
            if (r%sev*r%hh <= r%tiny_h .and. r%hh > 1.0e4_dp*r%tiny_h) then
                ! wrong way from the start along this step's polynomial:
                ! the step may be too long to resolve a push that a fast
                ! (axial) vibration reverses within it. Retry shorter
                ! before believing it (small friction coefficients).
                r%may_reuse = .false.
                r%pend = 0
                r%h = r%hh/16.0_dp
            else if (r%sev*r%hh <= r%tiny_h) then
                ! pushed the wrong way from the start: switch now
                call radau_stall(r, stat)
                if (stat%code /= 0) return
                call radau_switch(r, hist, stats, stat, .false., pars, sm)
                r%pend = 0
            else
                if (r%pend == 0) r%hcut = r%h
                r%may_reuse = .false.
                r%h = r%sev*r%hh
                r%pend = r%jev
                r%pkind = r%kev
                r%hpend = r%h
            end if
        else if (r%pend /= 0 .and. r%hh == r%hpend) then
            ! the targeted step ended just short of the root, unless the
            ! root went away on the shorter step: the switching function
            ! at its end is then not small against its change over the
            ! step (a root the longer step's polynomial made up, as right
            ! after a component started to slide from rest)
            if (near_root(r%es, r%y, r%z, r%hold0, r%hst, r%pend, r%pkind)) then
                r%jev = r%pend
                r%kev = r%pkind
            else
                r%h = max(r%h, r%hcut)
            end if
        end if
    end subroutine radau_locate

    !> Accept the step: the work by the collocation quadrature on the stages,
    !! the sensitivities, the new state, and the next step size.
    subroutine radau_accept(r, opts, stats, stat, pars, sm)
        type(radau_run_t), intent(inout) :: r
        type(integ_opts_t), intent(in) :: opts
        type(integ_stats_t), intent(inout) :: stats
        type(status_t), intent(inout) :: stat
        type(dyn_param_t), intent(in), optional :: pars(:)
        real(dp), intent(inout), optional :: sm(:, :)
        real(dp), parameter :: REUSE_THETA = 1.0e-3_dp
        integer :: i, j, n

        n = r%n
        if (r%es%nwork > 0) then
            do i = 1, 3
                r%ys = r%y + r%z(:, i)
                call dyn_eval(r%es, r%ts(i), r%ys, stat, power=r%pw(:, i))
            end do
            do j = 1, r%es%nwork
                r%work(j) = r%work(j) + r%hh*dot_product(r%pw(j, :), r%a(3, :))
            end do
        end if
        if (r%sens) then
            call radau_sens_step(r%es, r%it, pars, r%ts, r%y, r%z, r%hh, r%dmat, r%gam, r%mu, r%ti1, &
                                 r%ti2, r%tr, r%tc, opts%rtol, r%theta, sm, r%dzp, r%hsp, &
                                 stats%sens_passes, r%sws, stat)
            if (stat%code /= 0) return
        end if
        r%y = r%y + r%z(:, 3)
        r%f0 = r%f3
        if (r%it%rot) r%acc3 = (r%dmat(3, 1)*r%z(n + 1:2*n, 1) + r%dmat(3, 2)*r%z(n + 1:2*n, 2) &
                                + r%dmat(3, 3)*r%z(n + 1:2*n, 3))/r%hh
        r%t = r%t + r%hh
        if (r%atbreak) then
            ! on the breakpoint: the rates after it are new; the sensitivities
            ! jump where a parameter moves it
            r%t = r%bk(r%ib)
            if (r%sens) then
                call dyn_eval(r%es, nearest(r%t, -1.0_dp), r%y, stat, rates=r%ytmp)
                call dyn_eval(r%es, r%t, r%y, stat, rates=r%ev)
                if (stat%code /= 0) return
                call sens_break(r%es, pars, r%t, r%ytmp, r%ev, sm)
            end if
            r%ib = r%ib + 1
            r%have_f0 = .false.
        end if
        r%zprev = r%z
        r%hprev = r%hh
        r%have_prev = .true.
        stats%steps = stats%steps + 1
        r%first = .false.
        if (r%reject) r%hnew = min(r%hnew, r%hh)
        r%reject = .false.
        ! a step cut short at an output time does not shrink the next one
        if (r%clipped) then
            r%h = max(r%hnew, r%h)
        else
            r%h = r%hnew
        end if
        ! small steps with a fast-contracting Newton iteration: keep the
        ! Jacobian and the factors for the next step, and the step size
        ! when the controller would change it by less than 20 % upwards
        ! (RADAU5's THET and QUOT1, QUOT2)
        r%may_reuse = r%theta < REUSE_THETA .and. .not. r%clipped
        if (r%may_reuse .and. r%hnew >= r%hh .and. r%hnew <= 1.2_dp*r%hh) r%h = r%hh
        if (.not. all(ieee_is_finite(r%y))) then
            call set_status(stat, ERR_NUMERIC, RADAU_WHERE, 'state became non-finite at t = ' &
                            //fmt_real(r%t))
            return
        end if
        r%hold0 = r%hst(:, 3)
        if (r%jev == 0) r%nstall = 0
    end subroutine radau_accept

    !> The friction switch r%jev of kind r%kev at r%t: a velocity that reached
    !! zero is zero; the right-hand side changes, so the step-start rates are
    !! new. count_stall: a switch that changes no mode (a velocity touching
    !! zero) counts towards the stall limit: once is legitimate, again and again
    !! without a plain step between is no progress (roots ever closer together).
    subroutine radau_switch(r, hist, stats, stat, count_stall, pars, sm)
        type(radau_run_t), intent(inout) :: r
        type(history_t), intent(inout) :: hist
        type(integ_stats_t), intent(inout) :: stats
        type(status_t), intent(inout) :: stat
        logical, intent(in) :: count_stall
        type(dyn_param_t), intent(in), optional :: pars(:)
        real(dp), intent(inout), optional :: sm(:, :)
        integer :: jforce, nev0

        if (r%kev == EVENT_ZERO_VELOCITY) r%y(r%n + dyn_fric_dof(r%es, r%jev)) = 0.0_dp
        jforce = 0
        if (r%kev == EVENT_UNSTICK) jforce = r%jev
        if (r%sens) then
            call sens_event_pre(r%es, pars, r%t, r%y, r%kev, r%jev, r%hold0(r%jev), sm, r%fm, &
                                r%dtp, stat)
            if (stat%code /= 0) return
        end if
        nev0 = stats%events
        call apply_switch(r%es, r%y, r%t, r%kev, jforce, r%hold0, hist, stats, stat)
        if (stat%code /= 0) return
        if (count_stall) then
            if (stats%events == nev0) then
                call radau_stall(r, stat)
                if (stat%code /= 0) return
            else
                r%nstall = 0
            end if
        end if
        call set_stuck(r%es, r%it)
        if (r%sens) then
            call sens_event_post(r%es, r%t, r%y, r%fm, r%dtp, sm, stat)
            if (stat%code /= 0) return
            r%hsp = 0.0_dp
        end if
        r%have_f0 = .false.
        r%may_reuse = .false.
    end subroutine radau_switch

    !> One more switch without progress; an error past 4 per friction point.
    subroutine radau_stall(r, stat)
        type(radau_run_t), intent(inout) :: r
        type(status_t), intent(inout) :: stat

        r%nstall = r%nstall + 1
        if (r%nstall > 4*r%es%npt + 4) then
            call set_status(stat, ERR_NO_CONVERGENCE, RADAU_WHERE, &
                            'friction switching of component '//fmt_int(r%jev)// &
                            ' does not settle at t = '//fmt_real(r%t))
        end if
    end subroutine radau_stall

    ! ---------------------------------------------------------------------
    ! Forward sensitivities S = dy/dp (Eq. 135-140; docs/theory_dynamics.md)
    ! ---------------------------------------------------------------------

    !> The rates f = y' at the state y and their derivatives df(:, j) = d f
    !! / d p_j along the state sensitivities s(:, j) and the parameters
    !! pars (the variational equations of Eq. 135): what an acceleration
    !! observation needs (beamid_dynamic_experiments). The friction law of
    !! sys as set up (no sticking constraints).
    subroutine integ_rate_sens(sys, pars, t, y, s, f, df, stat)
        type(dyn_system_t), intent(in) :: sys
        type(dyn_param_t), intent(in) :: pars(:)
        real(dp), intent(in) :: t          !< time of y (s): the loads in time
        real(dp), intent(in) :: y(:), s(:, :)
        real(dp), intent(out) :: f(:), df(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: dl(:, :)
        df = 0.0_dp
        call dyn_eval(sys, t, y, stat, rates=f)
        if (stat%code /= 0 .or. size(s, 2) == 0) return
        allocate (dl(2*sys%npt, size(s, 2)))
        call sens_rates(sys, pars, t, y, f, s, df, dl, stat, .true.)
    end subroutine integ_rate_sens

    !> Rates of the sensitivities in rate form at the state y with rates f
    !! (the constrained ones): dS = (S_v, M^-1 (dF S + F_p - M_p a - (dM/dq
    !! S_q) a) constrained to the sticking components, p.S_q + d.S_v + e S_x
    !! + x'_p), the variational equations of Eq. 135. dl: the changes of the
    !! sticking components' constraint forces. with_p = .false.: the
    !! directional derivative along s alone (no parameter terms).
    subroutine sens_rates(es, pars, tn, y, f, s, ds, dl, stat, with_p, mldl)
        type(dyn_system_t), intent(in) :: es
        type(dyn_param_t), intent(in) :: pars(:)
        real(dp), intent(in) :: tn         !< time of y (s)
        real(dp), intent(in) :: y(:), f(:), s(:, :)
        real(dp), intent(out) :: ds(:, :), dl(:, :)
        type(status_t), intent(inout) :: stat
        logical, intent(in) :: with_p
        !> L D L^T factors of the constant mass matrix (absent or unallocated:
        !! its band LU es%mlu)
        real(dp), allocatable, intent(in), optional :: mldl(:, :)
        real(dp), allocatable :: kb(:, :), cb(:, :), r(:, :), bt(:)
        real(dp) :: b(es%n), p(es%n), d(es%n), t(es%n), fp(es%n)
        type(band_lu_t) :: lu
        real(dp) :: e, xp
        integer :: n, nb, j, kl, ku, nw, i
        logical :: coupled, ldl
        ldl = .false.
        if (present(mldl)) ldl = allocated(mldl)
        n = es%n
        kl = es%mesh%kl
        ku = es%mesh%ku
        nb = 2*kl + ku + 1
        nw = size(s, 2)
        coupled = dyn_velocity_coupled(es)
        allocate (kb(nb, n), r(n, nw))
        if (coupled) then
            allocate (cb(nb, n))
            call dyn_eval(es, tn, y, stat, kb=kb, cb=cb, b=b, p=p, d=d, e=e)
            do j = 1, nw
                call kc_mv(n, kl, ku, kb, cb, s(1:n, j), s(n + 1:2*n, j), r(:, j))
            end do
        else
            ! C is zero by construction: K S for every column in one sweep
            call dyn_eval(es, tn, y, stat, kb=kb, b=b, p=p, d=d, e=e)
            call kc_mv_many(n, kl, ku, nw, kb, s(1:n, :), r)
        end if
        if (es%rotary) then
            lu%n = n
            lu%kl = kl
            lu%ku = ku
            allocate (lu%ab(nb, n))
            call dyn_mass(es, y(1:n), lu%ab)
            call band_factor(lu, stat)
            if (stat%code /= 0) return
        end if
        dl = 0.0_dp
        ! the right-hand sides of all parameters, then one multi-column solve
        do j = 1, nw
            r(:, j) = -r(:, j)
            if (es%nx > 0) r(:, j) = r(:, j) + b*s(2*n + 1, j)
            t = 0.0_dp
            call dyn_dmass_dq_mv(es, y(1:n), s(1:n, j), f(n + 1:2*n), t)
            r(:, j) = r(:, j) - t
            xp = 0.0_dp
            if (with_p) then
                call dyn_eval(es, tn, y, stat, par=pars(j), fp=fp, xp=xp)
                t = 0.0_dp
                call dyn_dmass_mv(es, pars(j), y(1:n), f(n + 1:2*n), t)
                r(:, j) = r(:, j) + fp - t
            end if
            ds(1:n, j) = s(n + 1:2*n, j)
            if (es%nx > 0) ds(2*n + 1, j) = dot_product(p, s(1:n, j)) &
                                            + dot_product(d, s(n + 1:2*n, j)) + e*s(2*n + 1, j) + xp
        end do
        if (es%rotary) then
            call band_solve(lu, r)
        else if (ldl) then
            ! the constant M by its L D L^T factors, all columns in one solve
            ! (the right-hand sides as the rows of an nw x n matrix)
            allocate (bt(nw*n))
            do i = 1, n
                do j = 1, nw
                    bt((i - 1)*nw + j) = r(i, j)
                end do
            end do
            call ldlt_solve_real_many(n, kl, mldl, nw, bt)
            do i = 1, n
                do j = 1, nw
                    r(i, j) = bt((i - 1)*nw + j)
                end do
            end do
        else
            call band_solve(es%mlu, r)
        end if
        do j = 1, nw
            if (es%events) then
                if (es%rotary) then
                    call dyn_constrain(es, lu, r(:, j), dl(:, j), stat)
                else
                    call dyn_constrain(es, es%mlu, r(:, j), dl(:, j), stat)
                end if
            end if
            ds(n + 1:2*n, j) = r(:, j)
        end do
    end subroutine sens_rates

    !> mldl: the L D L^T factors (beamid_band's storage, kl + 1 rows) of the
    !! constant mass matrix when it is symmetric to round-off (the consistent
    !! mass of Eq. 92-97 with the point masses on its diagonal is) and positive
    !! definite, its lower half taken; left unallocated otherwise.
    subroutine mass_ldlt(sys, mldl)
        type(dyn_system_t), intent(in) :: sys
        real(dp), allocatable, intent(out) :: mldl(:, :)
        integer :: i, j, kl
        logical :: ok
        kl = sys%mesh%kl
        if (kl /= sys%mesh%ku .or. .not. allocated(sys%mb)) return
        if (.not. band_symmetric(sys%n, kl, sys%mb)) return
        allocate (mldl(kl + 1, sys%n))
        do j = 1, sys%n
            do i = j, min(sys%n, j + kl)
                mldl(1 + i - j, j) = sys%mb(2*kl + 1 + i - j, j)
            end do
        end do
        call ldlt_real(sys%n, kl, mldl, ok)
        if (.not. ok) deallocate (mldl)
    end subroutine mass_ldlt

    !> The RK4 step of the sensitivities (the variational equations on the
    !! same step, the derivative of the discrete map): from S at the state s
    !! over h, with the rates k1..k4 of the state's own step (rk_step: its
    !! stage states s + h/2 k1, s + h/2 k2, s + h k3 are those the variational
    !! equations need, so their rates are not evaluated again).
    subroutine rk_sens_step(es, pars, t, s, k1, k2, k3, k4, h, sm, stat, mldl, t_end)
        type(dyn_system_t), intent(in) :: es
        type(dyn_param_t), intent(in) :: pars(:)
        real(dp), intent(in) :: t          !< time of s (s)
        real(dp), intent(in) :: s(:), k1(:), k2(:), k3(:), k4(:), h
        real(dp), intent(inout) :: sm(:, :)
        type(status_t), intent(inout) :: stat
        !> L D L^T factors of the constant mass matrix (mass_ldlt; unallocated:
        !! its band LU)
        real(dp), allocatable, intent(in) :: mldl(:, :)
        !> time of the last stage (default t + h; rk_step's)
        real(dp), intent(in), optional :: t_end
        real(dp), allocatable :: y(:), st(:, :), d1(:, :), d2(:, :), d3(:, :), d4(:, :)
        real(dp), allocatable :: dl(:, :)
        real(dp) :: te
        integer :: m, nw
        te = t + h
        if (present(t_end)) te = t_end
        m = es%ncstate
        nw = size(sm, 2)
        allocate (y(m), st(m, nw), d1(m, nw), d2(m, nw), d3(m, nw), d4(m, nw), &
                  dl(2*es%npt, nw))
        call sens_rates(es, pars, t, s(1:m), k1(1:m), sm, d1, dl, stat, .true., mldl)
        y = s(1:m) + 0.5_dp*h*k1(1:m)
        st = sm + 0.5_dp*h*d1
        call sens_rates(es, pars, t + 0.5_dp*h, y, k2(1:m), st, d2, dl, stat, .true., mldl)
        y = s(1:m) + 0.5_dp*h*k2(1:m)
        st = sm + 0.5_dp*h*d2
        call sens_rates(es, pars, t + 0.5_dp*h, y, k3(1:m), st, d3, dl, stat, .true., mldl)
        y = s(1:m) + h*k3(1:m)
        st = sm + h*d3
        call sens_rates(es, pars, te, y, k4(1:m), st, d4, dl, stat, .true., mldl)
        sm = sm + (h/6.0_dp)*(d1 + 2.0_dp*(d2 + d3) + d4)
    end subroutine rk_sens_step

    !> At a breakpoint tb of the forcings: S+ = S- + (f- - f+) d tb/dp for each
    !! parameter that moves it (a step's start: the jump of its force), the
    !! rates f- before and f+ after it.
    subroutine sens_break(es, pars, tb, fm, fp, sm)
        type(dyn_system_t), intent(in) :: es
        type(dyn_param_t), intent(in) :: pars(:)
        real(dp), intent(in) :: tb, fm(:), fp(:)
        real(dp), intent(inout) :: sm(:, :)
        real(dp) :: d
        integer :: j
        do j = 1, size(pars)
            d = dyn_dbreak(es, pars(j), tb)
            if (d /= 0.0_dp) sm(:, j) = sm(:, j) + (fm - fp)*d
        end do
    end subroutine sens_break

    !> Before a friction switch at the state y (modes still the old ones):
    !! the rates f- and dt*/dp = -(g_y S- + g_p)/(g_y f-) of the switching
    !! function g: the velocity of component jev (EVENT_ZERO_VELOCITY) or
    !! mu N - |constraint force| (EVENT_UNSTICK, holdj its constraint force).
    subroutine sens_event_pre(es, pars, t, y, kind, jev, holdj, sm, fm, dtp, stat)
        type(dyn_system_t), intent(in) :: es
        type(dyn_param_t), intent(in) :: pars(:)
        real(dp), intent(in) :: t          !< time of the switch (s)
        real(dp), intent(in) :: y(:), holdj, sm(:, :)
        integer, intent(in) :: kind, jev
        real(dp), intent(out) :: fm(:), dtp(:)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: ds(:, :), dl(:, :), d1(:, :), dl1(:, :), pw(:)
        real(dp) :: den, sg
        integer :: i, j, nw
        nw = size(sm, 2)
        allocate (ds(size(y), nw), dl(2*es%npt, nw), d1(size(y), 1), dl1(2*es%npt, 1), &
                  pw(es%nwork))
        call dyn_eval(es, t, y, stat, rates=fm, power=pw)
        if (stat%code /= 0) return
        i = es%n + dyn_fric_dof(es, jev)
        dtp = 0.0_dp
        if (kind == EVENT_ZERO_VELOCITY) then
            den = fm(i)
            if (den /= 0.0_dp) dtp = -sm(i, :)/den
        else
            sg = sign(1.0_dp, holdj)
            call sens_rates(es, pars, t, y, fm, sm, ds, dl, stat, .true.)
            call sens_rates(es, pars, t, y, fm, reshape(fm, [size(fm), 1]), d1, dl1, stat, &
                            .false.)
            den = -sg*dl1(jev, 1)
            if (den /= 0.0_dp) then
                do j = 1, nw
                    dtp(j) = -(dyn_param_dcap(pars(j), (jev + 1)/2) - sg*dl(jev, j))/den
                end do
            end if
        end if
    end subroutine sens_event_pre

    !> After the switch: S+ = S- + (f- - f+) dt*/dp, and zero velocity
    !! sensitivity for the sticking components.
    subroutine sens_event_post(es, t, y, fm, dtp, sm, stat)
        type(dyn_system_t), intent(in) :: es
        real(dp), intent(in) :: t          !< time of the switch (s)
        real(dp), intent(in) :: y(:), fm(:), dtp(:)
        real(dp), intent(inout) :: sm(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: fp(:), pw(:)
        integer :: j
        allocate (fp(size(y)), pw(es%nwork))
        call dyn_eval(es, t, y, stat, rates=fp, power=pw)
        if (stat%code /= 0) return
        do j = 1, size(sm, 2)
            sm(:, j) = sm(:, j) + (fm - fp)*dtp(j)
        end do
        do j = 1, size(es%fmode)
            if (es%fric((j + 1)/2) /= 0.0_dp .and. es%fmode(j) == 0) &
                sm(es%n + dyn_fric_dof(es, j), :) = 0.0_dp
        end do
    end subroutine sens_event_post

    !> The staggered direct sensitivity step of Radau IIA: differentiate the
    !! converged stage equations (D Z)_i / h = f(y + Z_i, p) (M-form, as the
    !! Newton residuals) and solve the linear stage sensitivity system
    !!   (D dZ)_i / h = J(Y_i) (S + dZ_i) + f_p(Y_i)
    !! by iteration with the step's factored simplified-Newton matrices
    !! (the real and complex blocks), each pass one solve of each plus band
    !! products with the exact stage Jacobians, until the remaining error is
    !! below the tolerance; S_{n+1} = S_n + dZ_3 (stiffly accurate). All
    !! parameters go through each pass together (one sweep over each stage
    !! Jacobian for the products of every column, one multi-column solve per
    !! block, the stage Jacobians and f_p assembled once per step, no C
    !! products without velocity coupling); a column leaves the pass loop
    !! when it has converged.
    subroutine radau_sens_step(es, it, pars, t, y, z, hh, dmat, gam, mu, ti1, ti2, tr, tc, &
                               rtol, thn, sm, dzp, hp, passes, ws, stat)
        type(dyn_system_t), intent(in) :: es
        type(radau_t), intent(inout) :: it
        type(dyn_param_t), intent(in) :: pars(:)
        real(dp), intent(in) :: t(3)       !< the stage times (s)
        real(dp), intent(in) :: y(:), z(:, :), hh, dmat(3, 3), gam, ti1(3), tr(3), rtol
        !> the contraction of the step's Newton iteration (same matrices)
        real(dp), intent(in) :: thn
        complex(dp), intent(in) :: mu, ti2(3), tc(3)
        real(dp), intent(inout) :: sm(:, :)
        !> the previous step's stage sensitivities and step (hp = 0: none, as
        !! after a switch): the predictor, as the Newton iteration's
        real(dp), intent(inout) :: dzp(:, :, :), hp
        integer, intent(inout) :: passes          !< iteration passes, summed
        type(sens_work_t), intent(inout) :: ws    !< work arrays, kept across steps
        type(status_t), intent(inout) :: stat
        integer, parameter :: MAXIT = 40
        real(dp) :: e(3)
        integer :: n, m, nw, nb, j, iter, na, ja
        logical :: cz(3), update
        n = es%n
        m = es%ncstate
        nw = size(sm, 2)
        nb = 2*es%mesh%kl + es%mesh%ku + 1
        call sens_work_alloc(ws, nb, n, m, nw)
        call sens_stage_terms(es, pars, t, nw, y, z, hh, dmat, ws, e, cz)
        call sens_predict(es, it, pars, sm, dzp, hh, hp, dmat, ws, na)
        ! constant mass, no velocity coupling, no motor lag: the residuals after
        ! a correction from those of the pass before (sens_update)
        update = m == 2*n .and. .not. (it%rot .or. es%rotary .or. dyn_velocity_coupled(es))
        do iter = 1, MAXIT
            if (na == 0) exit
            if (update .and. iter > 1) then
                call sens_update(es, it, na, iter == 2, ws)
            else
                call sens_residuals(es, it, y, z, hh, dmat, sm, e, cz, na, ws)
            end if
            do ja = 1, na
                ws%w1(:, ja) = ti1(1)*ws%r(:, 1, ja) + ti1(2)*ws%r(:, 2, ja) &
                               + ti1(3)*ws%r(:, 3, ja)
                ws%w2(:, ja) = ti2(1)*ws%r(:, 1, ja) + ti2(2)*ws%r(:, 2, ja) &
                               + ti2(3)*ws%r(:, 3, ja)
            end do
            call solve_stage_many(es, it, gam/hh, mu/hh, na, ws%w1, ws%w2, ws%bt1, ws%bt2)
            call sens_correct(es, sm, hh, gam, mu, tr, tc, rtol, thn, iter, passes, ws, na)
        end do
        if (na > 0) then
            call set_status(stat, ERR_NO_CONVERGENCE, 'implicit sensitivities', &
                            'the stage sensitivity iteration did not converge in '// &
                            fmt_int(MAXIT)//' passes (step '//fmt_real(hh)//' s)')
            return
        end if
        do j = 1, nw
            if (pars(j)%kind == DP_NONE .and. all(sm(:, j) == 0.0_dp)) cycle
            sm(:, j) = sm(:, j) + ws%dz(:, 3, j)
            dzp(:, :, j) = ws%dz(:, :, j)
        end do
        hp = hh
    end subroutine radau_sens_step

    !> The exact stage Jacobians (ws%kb, cb, b, p, d and e; cz: a stage
    !! without velocity coupling, no drag, damping or motor, whose C products
    !! are skipped), the stage accelerations and the parameter derivatives of
    !! the forces at the converged stages (ws%cst), once per step for all
    !! nw parameters.
    subroutine sens_stage_terms(es, pars, tn, nw, y, z, hh, dmat, ws, e, cz)
        type(dyn_system_t), intent(in) :: es
        type(dyn_param_t), intent(in) :: pars(:)
        real(dp), intent(in) :: tn(3)      !< the stage times (s)
        integer, intent(in) :: nw
        real(dp), intent(in) :: y(:), z(:, :), hh, dmat(3, 3)
        type(sens_work_t), intent(inout) :: ws
        real(dp), intent(out) :: e(3)
        logical, intent(out) :: cz(3)
        real(dp) :: xp, ti
        integer :: n, nx, i, j
        logical :: coupled
        !> D / h: the stage derivatives (D Z)_i / h as products
        real(dp) :: dh(3, 3)
        type(status_t) :: nostat

        n = es%n
        dh = dmat/hh
        nx = es%ncstate - 2*n
        ! without velocity coupling C = dF/dv is zero by construction
        coupled = dyn_velocity_coupled(es)
        associate (kb => ws%kb, cb => ws%cb, acc => ws%acc, cst => ws%cst, t => ws%t, &
                   fp => ws%fp, ys => ws%ys)
            do i = 1, 3
                ys = y + z(:, i)
                ti = tn(i)
                if (coupled) then
                    call dyn_eval(es, ti, ys, nostat, kb=kb(:, :, i), cb=cb(:, :, i), &
                                  b=ws%b(:, i), p=ws%p(:, i), d=ws%d(:, i), e=e(i))
                    cz(i) = all(cb(:, :, i) == 0.0_dp)
                else
                    ! C is zero by construction: neither assembled nor scanned
                    call dyn_eval(es, ti, ys, nostat, kb=kb(:, :, i), b=ws%b(:, i), &
                                  p=ws%p(:, i), d=ws%d(:, i), e=e(i))
                    cz(i) = .true.
                end if
                acc(:, i) = dh(i, 1)*z(n + 1:2*n, 1) + dh(i, 2)*z(n + 1:2*n, 2) &
                             + dh(i, 3)*z(n + 1:2*n, 3)
                do j = 1, nw
                    call dyn_eval(es, ti, ys, nostat, par=pars(j), fp=fp, xp=xp)
                    if (allocated(pars(j)%dmb)) then
                        cst(1:n, i, j) = fp
                    else
                        t(:, 1) = 0.0_dp
                        call dyn_dmass_mv(es, pars(j), ys(1:n), acc(:, i), t(:, 1))
                        cst(1:n, i, j) = fp - t(:, 1)
                    end if
                    if (nx > 0) cst(n + 1, i, j) = xp
                end do
            end do
            ! a constant dM/dp (densities, point masses: dmb): (dM/dp) a_i of
            ! the three stages in one sweep over its band
            do j = 1, nw
                if (.not. allocated(pars(j)%dmb)) cycle
                if (ws%jr(1, j) == 0) then
                    ! its nonzero columns (a density: its beam's unknowns)
                    ws%jr(:, j) = [n, 1]
                    do i = 1, n
                        if (all(pars(j)%dmb(:, i) == 0.0_dp)) cycle
                        ws%jr(1, j) = min(ws%jr(1, j), i)
                        ws%jr(2, j) = max(ws%jr(2, j), i)
                    end do
                end if
                call kc_mv_many(n, es%mesh%kl, es%mesh%ku, 3, pars(j)%dmb, acc, ws%t3, &
                                jr=ws%jr(:, j))
                cst(1:n, :, j) = cst(1:n, :, j) - ws%t3
            end do
        end associate
    end subroutine sens_stage_terms

    !> The active columns (ws%act(1:na)) and their predictors (the previous
    !! step's stage polynomial, extrapolated); the linear rows q' = v hold from
    !! the start (and after every correction): the solves skip the products
    !! with their residual.
    subroutine sens_predict(es, it, pars, sm, dzp, hh, hp, dmat, ws, na)
        type(dyn_system_t), intent(in) :: es
        type(radau_t), intent(in) :: it
        type(dyn_param_t), intent(in) :: pars(:)
        real(dp), intent(in) :: sm(:, :), dzp(:, :, :), hh, hp, dmat(3, 3)
        type(sens_work_t), intent(inout) :: ws
        integer, intent(out) :: na
        real(dp) :: lsc(3, 3)
        integer :: n, i, j, k
        !> D / h: the stage derivatives (D Z)_i / h as products
        real(dp) :: dh(3, 3)

        n = es%n
        dh = dmat/hh
        na = 0
        if (hp > 0.0_dp) then
            do i = 1, 3
                lsc(:, i) = lagrange(1.0_dp + CNODE(i)*hh/hp)
            end do
        end if
        associate (dz => ws%dz)
            do j = 1, size(sm, 2)
                if (pars(j)%kind == DP_NONE .and. all(sm(:, j) == 0.0_dp)) cycle
                na = na + 1
                ws%act(na) = j
                if (hp > 0.0_dp) then
                    ! displacement (and torque) rows: the velocity rows follow
                    do i = 1, 3
                        dz(1:n, i, j) = lsc(1, i)*dzp(1:n, 1, j) + lsc(2, i)*dzp(1:n, 2, j) &
                                        + (lsc(3, i) - 1.0_dp)*dzp(1:n, 3, j)
                        dz(2*n + 1:, i, j) = lsc(1, i)*dzp(2*n + 1:, 1, j) &
                                             + lsc(2, i)*dzp(2*n + 1:, 2, j) &
                                             + (lsc(3, i) - 1.0_dp)*dzp(2*n + 1:, 3, j)
                    end do
                else
                    dz(:, :, j) = 0.0_dp
                end if
                do k = 1, it%nst
                    dz(it%stuck(k), :, j) = 0.0_dp
                end do
                do i = 1, 3
                    dz(n + 1:2*n, i, j) = dh(i, 1)*dz(1:n, 1, j) + dh(i, 2)*dz(1:n, 2, j) &
                                           + dh(i, 3)*dz(1:n, 3, j) - sm(n + 1:2*n, j)
                end do
                ws%errold(j) = huge(1.0_dp)
            end do
        end associate
    end subroutine sens_predict

    !> The residuals ws%r of the na active columns, velocity (and torque)
    !! rows only, stage by stage: the products of all columns with the stage
    !! Jacobian in one sweep over its band.
    subroutine sens_residuals(es, it, y, z, hh, dmat, sm, e, cz, na, ws)
        type(dyn_system_t), intent(in) :: es
        type(radau_t), intent(inout) :: it
        real(dp), intent(in) :: y(:), z(:, :), hh, dmat(3, 3), sm(:, :), e(3)
        logical, intent(in) :: cz(3)
        integer, intent(in) :: na
        type(sens_work_t), intent(inout) :: ws
        real(dp) :: xp
        integer :: n, m, nx, kl, ku, i, j, ja, k
        logical :: fused
        !> D / h: the stage derivatives (D Z)_i / h as products
        real(dp) :: dh(3, 3)

        n = es%n
        dh = dmat/hh
        m = es%ncstate
        nx = m - 2*n
        kl = es%mesh%kl
        ku = es%mesh%ku
        associate (kb => ws%kb, cb => ws%cb, b => ws%b, p => ws%p, d => ws%d, acc => ws%acc, &
                   cst => ws%cst, dz => ws%dz, r => ws%r, zd => ws%zd, t => ws%t, &
                   fp => ws%fp, ys => ws%ys, act => ws%act, wq => ws%wq, wv => ws%wv, &
                   zv => ws%zv, tm => ws%tm)
            do i = 1, 3
                ! with M0 (D dZ)_i / h (M-form) in the same sweep over the
                ! bands when the mass is constant and C is zero
                fused = cz(i) .and. .not. it%rot
                do ja = 1, na
                    j = act(ja)
                    wq(:, ja) = sm(1:n, j) + dz(1:n, i, j)
                    if (.not. cz(i) .or. nx > 0) wv(:, ja) = sm(n + 1:2*n, j) + dz(n + 1:2*n, i, j)
                    ! (D dZ)_i / h on the velocity rows
                    zv(:, ja) = dh(i, 1)*dz(n + 1:2*n, 1, j) + dh(i, 2)*dz(n + 1:2*n, 2, j) &
                                 + dh(i, 3)*dz(n + 1:2*n, 3, j)
                end do
                if (fused) then
                    call kc_mv_many(n, kl, ku, na, kb(:, :, i), wq, t, it%mb, zv)
                else if (cz(i)) then
                    call kc_mv_many(n, kl, ku, na, kb(:, :, i), wq, t)
                else
                    call kc_mv_many(n, kl, ku, na, kb(:, :, i), wq, t, cb(:, :, i), wv)
                    if (.not. it%rot) call kc_mv_many(n, kl, ku, na, it%mb, zv, tm)
                end if
                if (it%rot .or. es%rotary) ys(1:n) = y(1:n) + z(1:n, i)
                do ja = 1, na
                    j = act(ja)
                    if (it%rot) then
                        zd(n + 1:2*n) = zv(:, ja)
                        call to_mform(es, it, zd, ys(1:n))
                        tm(:, ja) = zd(n + 1:2*n)
                    end if
                    if (nx > 0) zd(m) = dh(i, 1)*dz(m, 1, j) + dh(i, 2)*dz(m, 2, j) &
                                         + dh(i, 3)*dz(m, 3, j)
                    if (fused) then
                        r(1:n, i, ja) = cst(1:n, i, j) - t(:, ja)
                    else
                        r(1:n, i, ja) = cst(1:n, i, j) - t(:, ja) - tm(:, ja)
                    end if
                    if (es%rotary) then
                        fp = 0.0_dp
                        call dyn_dmass_dq_mv(es, ys(1:n), wq(:, ja), acc(:, i), fp)
                        r(1:n, i, ja) = r(1:n, i, ja) - fp
                    end if
                    if (nx > 0) then
                        xp = sm(m, j) + dz(m, i, j)
                        r(1:n, i, ja) = r(1:n, i, ja) + b(:, i)*xp
                        r(n + 1, i, ja) = dot_product(p(:, i), wq(:, ja)) &
                                          + dot_product(d(:, i), wv(:, ja)) &
                                          + e(i)*xp + cst(n + 1, i, j) - zd(m)
                    end if
                    do k = 1, it%nst
                        r(it%stuck(k), i, ja) = 0.0_dp
                    end do
                end do
            end do
        end associate
    end subroutine sens_residuals

    !> The residuals of the na active columns after their last correction
    !! dZ (displacement rows ws%dlq; the velocity rows follow), without the
    !! mass products: the reduced solves invert lam^2 M + K0 exactly (K0 the
    !! iteration matrix's Jacobian it%kb), so the mass term M (D dZ_v)_i / h of
    !! the correction equals r_i - K0 dZ_q,i and the new residual, r_i minus
    !! the correction's K(Y_i) dZ_q,i and mass term, is (K0 - K(Y_i)) dZ_q,i.
    !! Constant mass, C = 0 and no motor lag only (radau_sens_step). first:
    !! the stage differences K0 - K(Y_i) are formed (once per step).
    subroutine sens_update(es, it, na, first, ws)
        type(dyn_system_t), intent(in) :: es
        type(radau_t), intent(in) :: it
        integer, intent(in) :: na
        logical, intent(in) :: first
        type(sens_work_t), intent(inout) :: ws
        integer :: n, kl, ku, i, ja, k, nb
        n = es%n
        kl = es%mesh%kl
        ku = es%mesh%ku
        nb = 2*kl + ku + 1
        if (first) then
            do i = 1, 3
                ws%kd(kl + 1:nb, :, i) = it%kb(kl + 1:nb, :) - ws%kb(kl + 1:nb, :, i)
            end do
        end if
        do i = 1, 3
            call kc_mv_many(n, kl, ku, na, ws%kd(:, :, i), ws%dlq(:, :, i), ws%t)
            do ja = 1, na
                ws%r(1:n, i, ja) = ws%t(:, ja)
                do k = 1, it%nst
                    ws%r(it%stuck(k), i, ja) = 0.0_dp
                end do
            end do
        end do
    end subroutine sens_update

    !> The corrections from the reduced solves (ws%w1, w2) of pass iter and
    !! convergence column by column: na becomes the number still active.
    subroutine sens_correct(es, sm, hh, gam, mu, tr, tc, rtol, thn, iter, passes, ws, na)
        type(dyn_system_t), intent(in) :: es
        real(dp), intent(in) :: sm(:, :), hh, gam, tr(3), rtol, thn
        complex(dp), intent(in) :: mu, tc(3)
        integer, intent(in) :: iter
        integer, intent(inout) :: passes, na
        type(sens_work_t), intent(inout) :: ws
        real(dp) :: ref, err, th, amax, dq, dv, sr, e(3), cv(3)
        complex(dp) :: cw(3)
        integer :: n, m, nx, i, j, k, ja, r

        n = es%n
        m = es%ncstate
        nx = m - 2*n
        ! w1, w2 hold (x, y = lam x - r_q) of the reduced solves: the
        ! displacement rows x and the velocity rows lam x (r_q = 0)
        cv = tr*(gam/hh)
        cw = tc*(mu/hh)
        associate (dz => ws%dz, w1 => ws%w1, w2 => ws%w2, dels => ws%dels, &
                   act => ws%act, errold => ws%errold)
            k = 0
            do ja = 1, na
                j = act(ja)
                ! the corrections of the three stages, row by row (one sweep)
                amax = 0.0_dp
                do r = 1, n
                    do i = 1, 3
                        dq = tr(i)*w1(r, ja) + real(tc(i)*w2(r, ja), dp)
                        dv = cv(i)*w1(r, ja) + real(cw(i)*w2(r, ja), dp)
                        dels(r, i) = dq
                        dels(n + r, i) = dv
                        dz(r, i, j) = dz(r, i, j) + dq
                        dz(n + r, i, j) = dz(n + r, i, j) + dv
                        amax = max(amax, abs(dz(r, i, j)))
                    end do
                end do
                if (nx > 0) then
                    do i = 1, 3
                        dels(m, i) = tr(i)*w1(n + 1, ja) + real(tc(i)*w2(n + 1, ja), dp)
                        dz(m, i, j) = dz(m, i, j) + dels(m, i)
                    end do
                end if
                ! error scale: the tolerance relative to this sensitivity's
                ! size (velocity rows as the displacement they cause over the
                ! step); the motor torque row on its own scale. The weighted
                ! mean squares of the three stages' corrections in one sweep
                ref = max(maxval(abs(sm(1:n, j))), amax, 1.0e-280_dp)
                e = 0.0_dp
                do r = 1, n
                    sr = 1.0_dp/(rtol*(abs(sm(r, j)) + ref))
                    e = e + (dels(r, :)*sr)**2
                end do
                do r = n + 1, 2*n
                    sr = 1.0_dp/(rtol*(abs(sm(r, j)) + ref))*hh
                    e = e + (dels(r, :)*sr)**2
                end do
                if (nx > 0) then
                    sr = 1.0_dp/(rtol*(abs(sm(m, j)) + max(abs(sm(m, j)), &
                                                          maxval(abs(dz(m, :, j))), 1.0e-280_dp)))
                    e = e + (dels(m, :)*sr)**2
                end if
                e = e/real(m, dp)
                err = max(e(1), e(2), e(3))
                passes = passes + 1
                ! converged when the remaining error th/(1 - th) |correction|
                ! is below the tolerance (th: the observed contraction; at the
                ! first pass the column's last observed one, carried across
                ! steps as CVODES carries its rate (the iteration matrices
                ! change little from step to step), before any the Newton
                ! one). The sensitivities of the seed's release agree with
                ! central differences of rtol 1e-11 runs to the same digits
                ! as with 1 % of it (the Newton test), at 8 passes per step
                ! for 4 parameters instead of 10.
                ! Below the tolerance and no longer contracting: the
                ! round-off floor of the residuals (tolerances near 1e-12)
                if (iter == 1) then
                    if (ws%thc(j) > 0.0_dp) then
                        th = min(max(ws%thc(j), 1.0e-4_dp), 0.9_dp)
                    else
                        th = min(max(thn, 1.0e-3_dp), 0.9_dp)
                    end if
                else
                    th = min(sqrt(err/max(errold(j), tiny(1.0_dp))), 0.9_dp)
                    ws%thc(j) = th
                end if
                if (th/(1.0_dp - th)*sqrt(err) <= 1.0_dp) cycle
                if (sqrt(err) <= 1.0_dp .and. err >= 0.8_dp*errold(j)) cycle
                errold(j) = err
                k = k + 1
                act(k) = j
                do i = 1, 3
                    ws%dlq(:, k, i) = dels(1:n, i)
                end do
            end do
            na = k
        end associate
    end subroutine sens_correct

    !> Work arrays of radau_sens_step, allocated on the first step.
    subroutine sens_work_alloc(ws, nb, n, m, nw)
        type(sens_work_t), intent(inout) :: ws
        integer, intent(in) :: nb, n, m, nw
        integer :: nr
        if (allocated(ws%kb)) return
        nr = n + (m - 2*n)
        allocate (ws%kb(nb, n, 3), ws%cb(nb, n, 3), ws%b(n, 3), ws%p(n, 3), ws%d(n, 3), &
                  ws%acc(n, 3), ws%cst(nr, 3, nw), ws%dz(m, 3, nw), ws%r(nr, 3, nw), &
                  ws%zd(m), ws%t(n, nw), ws%fp(n), ws%ys(m), ws%w1(nr, nw), ws%w2(nr, nw), &
                  ws%dels(m, 3), ws%errold(nw), ws%act(nw), ws%wq(n, nw), &
                  ws%wv(n, nw), ws%thc(nw), ws%zv(n, nw), ws%tm(n, nw), ws%t3(n, 3), &
                  ws%bt1(nw*n), ws%bt2(nw*n), ws%jr(2, nw), ws%dlq(n, nw, 3), ws%kd(nb, n, 3))
        ws%jr = 0
        ws%zd = 0.0_dp
        ws%thc = 0.0_dp
    end subroutine sens_work_alloc

    !> y(:, c) = K x(:, c) (+ C v(:, c)) for the na columns of x (and v): one
    !! sweep over the band storage of K (and C) serves every column.
    pure subroutine kc_mv_many(n, kl, ku, na, kb, x, y, cb, v, jr)
        integer, intent(in) :: n, kl, ku, na
        real(dp), intent(in) :: kb(2*kl + ku + 1, n), x(:, :)
        real(dp), intent(inout) :: y(:, :)
        real(dp), intent(in), optional :: cb(2*kl + ku + 1, n), v(:, :)
        !> the columns jr(1):jr(2) hold every nonzero of kb (and cb)
        integer, intent(in), optional :: jr(2)
        integer :: j, c, i1, i2, k, i0, j1, j2
        k = kl + ku + 1
        y(1:n, 1:na) = 0.0_dp
        j1 = 1
        j2 = n
        if (present(jr)) then
            j1 = jr(1)
            j2 = jr(2)
        end if
        do j = j1, j2
            i1 = max(1, j - ku)
            i2 = min(n, j + kl)
            i0 = k + i1 - j
            if (present(cb)) then
                do c = 1, na
                    y(i1:i2, c) = y(i1:i2, c) + x(j, c)*kb(i0:i0 + i2 - i1, j) &
                                  + v(j, c)*cb(i0:i0 + i2 - i1, j)
                end do
            else
                do c = 1, na
                    y(i1:i2, c) = y(i1:i2, c) + x(j, c)*kb(i0:i0 + i2 - i1, j)
                end do
            end if
        end do
    end subroutine kc_mv_many

    !> The real (lam1 = gamma/h) and the complex (lam2 = mu/h) block of the
    !! stage sensitivity system for na right-hand sides at once, in the
    !! reduced layout of the iteration: in, w(1:n, c) the velocity rows
    !! (M-form) and w(n + 1, c) the torque row (motor lag), the displacement
    !! rows being zero; out, the displacement correction x in w(1:n, c) (the
    !! velocity correction is lam x) and the torque correction in w(n + 1, c).
    !! One routine for both kinds: the blocks are always solved together.
    subroutine solve_stage_many(sys, it, lam1, lam2, na, w1, w2, bt1, bt2)
        type(dyn_system_t), intent(in) :: sys
        type(radau_t), intent(inout) :: it
        real(dp), intent(in) :: lam1
        complex(dp), intent(in) :: lam2
        integer, intent(in) :: na
        real(dp), intent(inout), contiguous :: w1(:, :)
        complex(dp), intent(inout), contiguous :: w2(:, :)
        !> work: the right-hand sides as the rows of an na x nc matrix (the
        !! many-column solves), at least na nc long
        real(dp), intent(inout), contiguous :: bt1(:)
        complex(dp), intent(inout), contiguous :: bt2(:)
        integer :: n, c, j
        n = sys%nc
        if (na == 0) return
        if (sys%nx > 0) then
            ! the torque row eliminated (Eq. 158 lag): the motor column b
            ! (w(n + 1, c) keeps the torque row's right-hand side)
            do c = 1, na
                w1(1:n, c) = w1(1:n, c) + it%b*w1(n + 1, c)/(lam1 - it%e)
                w2(1:n, c) = w2(1:n, c) + it%b*w2(n + 1, c)/(lam2 - it%e)
            end do
        end if
        do c = 1, it%nst
            w1(it%stuck(c), 1:na) = 0.0_dp
            w2(it%stuck(c), 1:na) = (0.0_dp, 0.0_dp)
        end do
        if (it%sym) then
            do j = 1, n
                do c = 1, na
                    bt1((j - 1)*na + c) = w1(j, c)
                    bt2((j - 1)*na + c) = w2(j, c)
                end do
            end do
            call ldlt_solve_real_many(n, sys%ckl, it%s1, na, bt1)
            call ldlt_solve_cplx_many(n, sys%ckl, it%s2, na, bt2)
            do c = 1, merge(na, 0, it%nlr > 0)
                call lr_real(it, bt1(c:na*n:na))
                call lr_cplx(it, bt2(c:na*n:na))
            end do
            do j = 1, n
                do c = 1, na
                    w1(j, c) = bt1((j - 1)*na + c)
                    w2(j, c) = bt2((j - 1)*na + c)
                end do
            end do
        else
            do c = 1, na
                call band_solve(it%lu1, w1(1:n, c))
                it%zrhs = w2(1:n, c)
                call zband_solve(it%lu2, it%zrhs)
                w2(1:n, c) = it%zrhs
            end do
        end if
        if (sys%nx > 0) then
            do c = 1, na
                w1(n + 1, c) = (w1(n + 1, c) + dot_product(it%p + lam1*it%d, w1(1:n, c))) &
                               /(lam1 - it%e)
                w2(n + 1, c) = (w2(n + 1, c) + sum((it%p + lam2*it%d)*w2(1:n, c)))/(lam2 - it%e)
            end do
        end if
    end subroutine solve_stage_many


end module beamid_integrators
