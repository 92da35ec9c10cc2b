!> Release experiments (Chapter IV.2, V.2): the finite element chain held in
!! static equilibrium under a tip load, released at rest at t = 0 (with the
!! tip motor when motor_gain > 0), integrated to the output times, with the
!! energy ledger (Eq. 118-122, 155-156) and, on request, the forward
!! sensitivities of the outputs with respect to model parameters and the
!! release load's components (Eq. 135-140, 161-162; docs/theory_dynamics.md).
!!
!! This is the one library routine behind beamid.simulate (through the f2py
!! binding beamid_api_dynamics), the batch program's &simulate decks and the
!! dynamic experiments of the estimation.
!!
!! Parameters are addressed by their index in the model's flat parameter
!! vector (beamid_model: param_index_*, param_name); the release load's
!! components follow it: index param_count(nbeams) + LOAD_FX, LOAD_FY,
!! LOAD_MOMENT (release_load_index).
module beamid_release
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK, ERR_INPUT, set_status, fmt_int, fmt_real
    use beamid_model, only: chain_t, param_count, param_name
    use beamid_fe_assembly, only: fe_load_t
    use beamid_fe_static, only: fe_newton_opts_t, fe_solve_info_t, fe_solve_static
    use beamid_dynamics, only: dyn_system_t, dyn_setup, dyn_set_modes, dyn_to_coords, &
                               dyn_to_physical, dyn_energy, dyn_tip, dyn_torque, dyn_rates, &
                               FRICTION_SIGN, dyn_param_t, dyn_param_setup, &
                               dyn_static_sens, dyn_output_sens, dyn_add_forcing, DP_FORCING, &
                               DP_NONE
    use beamid_loads, only: tip_history_t, history_check
    use beamid_hub, only: hub_forcing_t, hub_setup
    use beamid_integrators, only: integ_opts_t, integ_stats_t, history_t, integrate, &
                                  METHOD_IMPLICIT
    implicit none
    private

    public :: release_spec_t, release_out_t, release_response, release_load_index
    public :: release_add_loads
    !> The wrt index of the initial tip normal velocity v0 (spec%v0): its
    !! sensitivity starts at ds/dv0(0) = (0, q / w_tip(q)) and has no forcing.
    integer, parameter, public :: WRT_V0 = -1
    public :: release_quantity_name, release_wrt_name
    public :: NQTY, QTY_U_TIP, QTY_W_TIP, QTY_X_TIP, QTY_Y_TIP, QTY_TIP_ANGLE, QTY_X_ELBOW, &
              QTY_Y_ELBOW, QTY_MOTOR_TORQUE, QTY_ENERGY
    public :: NLOAD, LOAD_FX, LOAD_FY, LOAD_MOMENT

    !> Exported quantities of a release (rows of release_out_t%y). The elbow
    !! is mass point 1 (joint 1; the tip of a single beam). x = s + u, y = w.
    integer, parameter :: QTY_U_TIP = 1, QTY_W_TIP = 2, QTY_X_TIP = 3, QTY_Y_TIP = 4, &
                          QTY_TIP_ANGLE = 5, QTY_X_ELBOW = 6, QTY_Y_ELBOW = 7, &
                          QTY_MOTOR_TORQUE = 8, QTY_ENERGY = 9, NQTY = 9
    character(len=12), parameter :: QTY_NAMES(NQTY) = [character(len=12) :: &
        'u_tip', 'w_tip', 'x_tip', 'y_tip', 'tip_angle', 'x_elbow', 'y_elbow', &
        'motor_torque', 'energy']
    !> Components of the release load, after the model parameters in wrt.
    integer, parameter :: LOAD_FX = 1, LOAD_FY = 2, LOAD_MOMENT = 3, NLOAD = 3
    character(len=6), parameter :: LOAD_NAMES(NLOAD) = [character(len=6) :: &
        'fx', 'fy', 'moment']

    !> What a release experiment is: mesh, load, motor and integration.
    type :: release_spec_t
        integer :: elements_per_beam = 4
        type(fe_load_t) :: load               !< the static load held before t = 0
        real(dp) :: motor_gain = 0.0_dp       !< g of Eq. 150 (0: no motor)
        integer :: integrator = METHOD_IMPLICIT
        real(dp) :: rtol = 0.0_dp             !< 0: the integrator's default (1e-9)
        real(dp) :: atol = 0.0_dp             !< 0: rtol
        real(dp) :: dt = 0.0_dp               !< RK4 step, 0: 1e-5 s
        real(dp) :: h0 = 0.0_dp               !< implicit first step, 0: default
        integer :: friction = FRICTION_SIGN
        real(dp) :: friction_velocity = 1.0e-4_dp
        !> truncated modal model: retained mode numbers (unallocated or empty:
        !! the full model; no sensitivities in the modal model)
        integer, allocatable :: modes(:)
        !> start from this state instead of the static shape (its sensitivity
        !! is then zero)
        real(dp), allocatable :: y_init(:)
        !> the initial tip normal velocity (m/s): the static shape q starts
        !! with the velocity field v0 q / w_tip(q) (0: at rest)
        real(dp) :: v0 = 0.0_dp
        !> progress(1) follows the output times reached (integ_opts_t%progress)
        real(dp), pointer :: progress(:) => null()
        !> also return the quantities' time derivatives (release_out_t%rate):
        !! the column of a record's clock offset (beamid_inverse, EV_T0)
        logical :: rates = .false.
        !> load histories at the tip from t = 0 (beamid_loads; their tip
        !! indices are set here); their parameters follow the release load's
        !! components in wrt, history by history
        type(tip_history_t), allocatable :: histories(:)
        !> a prescribed hub rotation (beamid_hub: the spin-up law to w_s in T),
        !! after the histories (its parameter w_s follows theirs in wrt)
        logical :: hub = .false.
        real(dp) :: hub_ws = 0.0_dp, hub_period = 0.0_dp
        !> the hub angle as a table instead (rows (t, angle), scaled by hub_ws)
        real(dp), allocatable :: hub_table(:, :)
    end type release_spec_t

    !> The response at the output times.
    type :: release_out_t
        real(dp), allocatable :: y(:, :)          !< (NQTY, nt), rows QTY_*
        real(dp), allocatable :: dy(:, :, :)      !< (NQTY, nt, size(wrt))
        !> (NQTY, nt) d y / d t at the output times (spec%rates; energy: 0)
        real(dp), allocatable :: rate(:, :)
        real(dp), allocatable :: ledger(:, :)     !< (4, nt): kinetic, strain, total, numerical
        real(dp), allocatable :: tip(:, :)        !< (3, nt): u, w, angle
        !> state sensitivities dy/dp (nstate, nt, size(wrt))
        real(dp), allocatable :: dstates(:, :, :)
        type(history_t) :: hist                   !< states, torque, energies, work, events
        type(integ_stats_t) :: stats
        integer :: nfree = 0, nstate = 0, nwork = 0
    end type release_out_t

contains

    !> Index in wrt of release load component `comp` (LOAD_*).
    pure integer function release_load_index(nbeams, comp)
        integer, intent(in) :: nbeams, comp
        release_load_index = param_count(nbeams) + comp
    end function release_load_index

    !> Name of exported quantity k (QTY_*), '' outside the table.
    pure function release_quantity_name(k) result(name)
        integer, intent(in) :: k
        character(len=:), allocatable :: name
        if (k < 1 .or. k > NQTY) then
            name = ''
        else
            name = trim(QTY_NAMES(k))
        end if
    end function release_quantity_name

    !> Name of a wrt index: the parameter's, or load_fx, load_fy, load_moment.
    pure function release_wrt_name(nbeams, index) result(name)
        integer, intent(in) :: nbeams, index
        character(len=:), allocatable :: name
        integer :: k
        k = index - param_count(nbeams)
        if (k >= 1 .and. k <= NLOAD) then
            name = 'load_'//trim(LOAD_NAMES(k))
        else
            name = param_name(nbeams, index)
        end if
    end function release_wrt_name

    !> Release the chain at the static equilibrium under spec%load, integrate
    !! to t_out (ascending, >= 0; t = 0 gives the static shape) and return the
    !! exported quantities and their sensitivities with respect to the
    !! parameters wrt (indices into the parameter vector, then the load's).
    subroutine release_response(chain, spec, t_out, wrt, out, stat)
        type(chain_t), intent(in) :: chain
        type(release_spec_t), intent(in) :: spec
        real(dp), intent(in) :: t_out(:)
        integer, intent(in) :: wrt(:)
        type(release_out_t), intent(out) :: out
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'release_response'
        type(dyn_system_t) :: sys
        type(fe_newton_opts_t) :: nopts
        type(fe_solve_info_t) :: sinfo
        type(integ_opts_t) :: opts
        type(dyn_param_t), allocatable :: pars(:)
        real(dp), allocatable :: y0(:), q(:), yc(:), s0(:, :)
        real(dp) :: e0, u, w, ang
        integer :: k, n, nt, nw, j, l, nhp, base, ip
        logical :: modal

        nt = size(t_out)
        nw = size(wrt)
        call dyn_setup(chain, spec%elements_per_beam, spec%motor_gain, spec%friction, &
                       spec%friction_velocity, sys, stat)
        if (stat%code /= STATUS_OK) return
        modal = .false.
        if (allocated(spec%modes)) modal = size(spec%modes) > 0
        if (modal) then
            if (nw > 0) then
                call set_status(stat, ERR_INPUT, where, 'sensitivities are not available '// &
                                'in the truncated modal model (modes): use the full model')
                return
            end if
            call dyn_set_modes(sys, spec%modes, stat)
            if (stat%code /= STATUS_OK) return
        end if
        call release_add_loads(sys, spec, t_out(max(1, nt)), nhp, stat)
        if (stat%code /= STATUS_OK) return
        base = param_count(chain%nbeams) + NLOAD
        do j = 1, nw
            if (wrt(j) == WRT_V0) cycle
            if (wrt(j) < 1 .or. wrt(j) > base + nhp) then
                call set_status(stat, ERR_INPUT, where, 'wrt('//fmt_int(j)//') = '// &
                                fmt_int(wrt(j))//', expected 1..'//fmt_int(base + nhp)// &
                                ' (a parameter index, then fx, fy, moment of the load, '// &
                                'then the load histories'' parameters)')
                return
            end if
        end do
        n = sys%n
        out%nfree = n
        out%nstate = sys%nstate
        out%nwork = sys%nwork
        allocate (y0(sys%nstate), q(n), s0(sys%nstate, nw), pars(nw))
        do j = 1, nw
            if (wrt(j) == WRT_V0) then
                pars(j)%kind = DP_NONE
                cycle
            end if
            if (wrt(j) > base) then
                ! parameter ip of history l (DP_FORCING)
                ip = wrt(j) - base
                do l = 1, sys%nloads
                    if (ip <= sys%loads(l)%f%nparams()) exit
                    ip = ip - sys%loads(l)%f%nparams()
                end do
                pars(j)%kind = DP_FORCING
                pars(j)%k = l
                pars(j)%ip = ip
                cycle
            end if
            call dyn_param_setup(sys, chain, wrt(j) - param_count(chain%nbeams), &
                                 wrt(j), pars(j), stat)
            if (stat%code /= STATUS_OK) return
        end do
        y0 = 0.0_dp
        s0 = 0.0_dp
        if (allocated(spec%y_init)) then
            if (size(spec%y_init) /= sys%nstate) then
                call set_status(stat, ERR_INPUT, where, 'initial state has '// &
                                fmt_int(size(spec%y_init))//' entries, expected '// &
                                fmt_int(sys%nstate))
                return
            end if
            y0 = spec%y_init
            if (spec%v0 /= 0.0_dp .or. any(wrt == WRT_V0)) then
                call set_status(stat, ERR_INPUT, where, 'an initial velocity v0 with a '// &
                                'given initial state: expected one of them')
                return
            end if
        else
            q = 0.0_dp
            call fe_solve_static(sys%mesh, spec%load, q, .false., nopts, sinfo, stat)
            if (stat%code /= STATUS_OK) return
            y0(1:n) = q
            ! the released shape's sensitivity (implicit function theorem on the
            ! static equilibrium, the Newton tangent); zero velocity sensitivity
            if (nw > 0) call dyn_static_sens(sys, spec%load, q, pars, s0(1:n, :), stat)
            if (stat%code /= STATUS_OK) return
            if (spec%v0 /= 0.0_dp .or. any(wrt == WRT_V0)) then
                ! the initial velocity field: the static shape scaled to tip
                ! normal velocity v0; d/dv0 starts as that field (no forcing)
                call dyn_tip(sys, q, u, w, ang)
                if (abs(w) <= 1.0e-12_dp*sum(chain%length)) then
                    call set_status(stat, ERR_INPUT, where, 'an initial velocity v0 = '// &
                                    fmt_real(spec%v0)//', but the static shape has no tip '// &
                                    'deflection (w_tip = '//fmt_real(w)//'); expected a '// &
                                    'release load that deflects the tip')
                    return
                end if
                y0(n + 1:2*n) = spec%v0*q/w
                do j = 1, nw
                    if (wrt(j) == WRT_V0) s0(n + 1:2*n, j) = q/w
                end do
            end if
        end if
        opts%method = spec%integrator
        if (spec%dt > 0.0_dp) opts%dt = spec%dt
        if (spec%rtol > 0.0_dp) opts%rtol = spec%rtol
        opts%atol = merge(spec%atol, opts%rtol, spec%atol > 0.0_dp)
        if (spec%h0 > 0.0_dp) opts%h0 = spec%h0
        opts%progress => spec%progress
        if (spec%dt < 0.0_dp .or. spec%rtol < 0.0_dp .or. spec%atol < 0.0_dp) then
            call set_status(stat, ERR_INPUT, where, 'dt, rtol and atol must not be '// &
                            'negative (0: default)')
            return
        end if
        if (nw > 0) then
            call integrate(sys, y0, t_out, opts, out%hist, out%stats, stat, pars, s0, &
                           out%dstates)
        else
            allocate (out%dstates(sys%nstate, nt, 0))
            call integrate(sys, y0, t_out, opts, out%hist, out%stats, stat)
        end if
        if (stat%code /= STATUS_OK) return
        ! the modal model starts from the projection of y0 on its modes
        allocate (yc(sys%ncstate))
        call dyn_to_coords(sys, y0, yc)
        call dyn_to_physical(sys, yc, y0)
        call dyn_energy(sys, y0(1:n), y0(n + 1:2*n), u, w)
        e0 = u + w
        allocate (out%y(NQTY, nt), out%dy(NQTY, nt, nw), out%ledger(4, nt), out%tip(3, nt), &
                  source=0.0_dp)
        do k = 1, nt
            associate (y => out%hist%y(:, k))
                call dyn_tip(sys, y(1:n), u, w, ang)
                out%tip(:, k) = [u, w, ang]
                out%ledger(1:3, k) = [out%hist%kinetic(k), out%hist%potential(k), &
                                      out%hist%kinetic(k) + out%hist%potential(k)]
                out%ledger(4, k) = out%ledger(3, k) - e0 - sum(out%hist%work(:, k))
                out%y(QTY_U_TIP, k) = u
                out%y(QTY_W_TIP, k) = w
                out%y(QTY_X_TIP, k) = sum(chain%length) + u
                out%y(QTY_Y_TIP, k) = w
                out%y(QTY_TIP_ANGLE, k) = ang
                out%y(QTY_X_ELBOW, k) = chain%length(1) + y(sys%iu(1))
                out%y(QTY_Y_ELBOW, k) = y(sys%iw(1))
                out%y(QTY_MOTOR_TORQUE, k) = out%hist%torque(k)
                out%y(QTY_ENERGY, k) = out%ledger(3, k)
                do j = 1, nw
                    call dyn_output_sens(sys, pars(j), y, out%dstates(:, k, j), &
                                         out%dy(QTY_U_TIP:QTY_W_TIP, k, j), &
                                         out%dy(QTY_TIP_ANGLE, k, j), &
                                         out%dy(QTY_MOTOR_TORQUE, k, j), &
                                         out%dy(QTY_ENERGY, k, j))
                    out%dy(QTY_X_TIP, k, j) = out%dy(QTY_U_TIP, k, j)
                    out%dy(QTY_Y_TIP, k, j) = out%dy(QTY_W_TIP, k, j)
                    out%dy(QTY_X_ELBOW, k, j) = out%dstates(sys%iu(1), k, j)
                    out%dy(QTY_Y_ELBOW, k, j) = out%dstates(sys%iw(1), k, j)
                end do
            end associate
        end do
        if (spec%rates) then
            allocate (out%rate(NQTY, nt), source=0.0_dp)
            do k = 1, nt
                ! at t = 0 the chain is at rest: every rate is 0 there
                if (t_out(k) <= 0.0_dp) cycle
                call quantity_rates(sys, t_out(k), out%hist%y(:, k), out%rate(:, k), stat)
                if (stat%code /= STATUS_OK) return
            end do
        end if
    end subroutine release_response

    !> Add spec's load histories (one forcing each, acting at the tip) and
    !! its prescribed hub rotation to the system `sys`, each history checked
    !! against the experiment's end t_end; nhp = their parameters' number
    !! (the wrt indices after the release load's). The estimation's station
    !! observations build their system the same way (beamid_dynamic_experiments).
    subroutine release_add_loads(sys, spec, t_end, nhp, stat)
        type(dyn_system_t), intent(inout) :: sys
        type(release_spec_t), intent(in) :: spec
        real(dp), intent(in) :: t_end
        integer, intent(out) :: nhp
        type(status_t), intent(inout) :: stat
        type(tip_history_t) :: th
        type(hub_forcing_t) :: hub
        integer :: l
        nhp = 0
        if (allocated(spec%histories)) then
            do l = 1, size(spec%histories)
                th = spec%histories(l)
                call history_check(th%hist, 'load history '//fmt_int(l)//' ('// &
                                   th%work_name()//')', t_end, stat)
                if (stat%code /= STATUS_OK) return
                th%iw = sys%iw(sys%npt)
                th%iu = sys%iu(sys%npt)
                th%idw = sys%idw(sys%npt)
                th%idu = sys%idu(sys%npt)
                call dyn_add_forcing(sys, th)
                nhp = nhp + th%nparams()
            end do
        end if
        if (spec%hub) then
            if (allocated(spec%hub_table)) then
                call hub_setup(sys, spec%hub_ws, spec%hub_period, 'hub angle table', hub, &
                               stat, spec%hub_table(1, :), spec%hub_table(2, :))
            else
                call hub_setup(sys, spec%hub_ws, spec%hub_period, 'hub law', hub, stat)
            end if
            if (stat%code /= STATUS_OK) return
            call dyn_add_forcing(sys, hub)
            nhp = nhp + hub%nparams()
        end if
    end subroutine release_add_loads

    !> Time derivatives of the exported quantities in state y (rows QTY_*):
    !! the positions' from the velocities in y, the tip angle's by the chain
    !! rule of atan2(w', 1 + u'), the motor torque's from the state's rate
    !! (dyn_rates: the acceleration M^-1 F, or the lag's T'). Energy: 0.
    subroutine quantity_rates(sys, t, y, rate, stat)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: t          !< time (s): the load histories'
        real(dp), intent(in) :: y(:)
        real(dp), intent(out) :: rate(:)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: yd(:), power(:)
        real(dp) :: a1, a2, torque
        integer :: n, k
        n = sys%n
        k = sys%npt
        rate = 0.0_dp
        associate (v => y(n + 1:2*n))
            rate(QTY_U_TIP) = v(sys%iu(k))
            rate(QTY_W_TIP) = v(sys%iw(k))
            rate(QTY_X_TIP) = rate(QTY_U_TIP)
            rate(QTY_Y_TIP) = rate(QTY_W_TIP)
            a1 = 1.0_dp + y(sys%idu(k))
            a2 = y(sys%idw(k))
            rate(QTY_TIP_ANGLE) = (a1*v(sys%idw(k)) - a2*v(sys%idu(k)))/(a1*a1 + a2*a2)
            rate(QTY_X_ELBOW) = v(sys%iu(1))
            rate(QTY_Y_ELBOW) = v(sys%iw(1))
        end associate
        if (sys%motor == 0.0_dp) return
        allocate (yd(size(y)), power(sys%nwork))
        call dyn_rates(sys, t, y, yd, power, torque, stat)
        if (stat%code /= STATUS_OK) return
        if (sys%nx > 0) then
            rate(QTY_MOTOR_TORQUE) = yd(2*n + 1)
        else
            ! T = -r g Psidot, Psidot = (1 + u') w'_t - w' u'_t at the tip
            rate(QTY_MOTOR_TORQUE) = -sys%motor*(y(n + sys%idu(k))*y(n + sys%idw(k)) + &
                a1*yd(n + sys%idw(k)) - y(n + sys%idw(k))*y(n + sys%idu(k)) - &
                a2*yd(n + sys%idu(k)))
        end if
    end subroutine quantity_rates

end module beamid_release
