!> Load histories of a dynamic experiment (issue 28): a scalar history g(t)
!! applied at the tip as a force component, a torque, or the open-loop
!! torque of the Chapter V tip motor. Each history is one forcing of the
!! dynamic system (beamid_forcing) with its own work line.
!!
!! Histories g(t) (t0 the start, T the duration, A the amplitude):
!! - table: piecewise linear through (t_i, A v_i); before the first row the
!!   first value, after the last row the last value (the rows are the
!!   breakpoints the integrators step onto);
!! - half-sine: A sin(pi (t - t0)/T) for t0 <= t < t0 + T, else 0 (an
!!   impact hammer's pulse);
!! - step: A for t >= t0, else 0;
!! - chirp: A sin(2 pi (f0 s + (f1 - f0) s^2/(2 T))), s = t - t0, for
!!   t0 <= t < t0 + T, else 0 (a linear sweep from f0 to f1 Hz).
!! All are right-continuous: at a jump the value is the one after it.
!!
!! Parameters of a history (sensitivities, DP_FORCING): 1 its amplitude A
!! (a table's scale), and for the half-sine 2 its duration T. None moves a
!! time where the history jumps (the half-sine is continuous at its end), so
!! the state sensitivities need no jump condition at the breakpoints.
!!
!! Targets at the tip (free indices of the tip node): fx on u, fy on w, a
!! torque tau acting on the tip angle psi = atan2(w', 1 + u') (generalized
!! force tau grad psi, the exact moment of fe_tip_load), or the open-loop
!! motor torque acting as the Chapter V motor does, T [(1 + u') dw' - w' du']
!! (Eq. 151-152).
module beamid_loads
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use beamid_kinds, only: dp, pi
    use beamid_status, only: status_t, set_status, ERR_INPUT, fmt_int, fmt_real
    use beamid_band, only: band_add
    use beamid_forcing, only: forcing_t
    implicit none
    private

    public :: load_history_t, tip_history_t
    public :: history_value, history_dvalue, history_nparams, history_breaks
    public :: HIST_TABLE, HIST_HALF_SINE, HIST_STEP, HIST_CHIRP, HIST_SPIN_UP
    public :: TARGET_FX, TARGET_FY, TARGET_TORQUE, TARGET_MOTOR, TARGET_NAMES, HIST_NAMES
    public :: TARGET_HUB
    public :: HIST_PARAM_NAMES, LD_NSPEC, histories_from_columns, history_check

    integer, parameter :: HIST_TABLE = 1, HIST_HALF_SINE = 2, HIST_STEP = 3, HIST_CHIRP = 4
    !> the hub's spin-up law (beamid_hub; a hub column of kind HIST_TABLE is
    !! its angle table): not a tip history
    integer, parameter :: HIST_SPIN_UP = 5
    integer, parameter :: TARGET_FX = 1, TARGET_FY = 2, TARGET_TORQUE = 3, TARGET_MOTOR = 4
    !> the hub's rotation (beamid_hub), not a tip history
    integer, parameter :: TARGET_HUB = 5
    !> names of the targets (the tip histories' work lines) and history
    !! kinds, by code: the one definition the deck reader and the Python
    !! front read (api_code_names)
    character(len=*), parameter :: TARGET_NAMES(5) = [character(len=11) :: 'tip_fx', &
                                                      'tip_fy', 'tip_torque', 'motor_open', &
                                                      'hub']
    character(len=*), parameter :: HIST_NAMES(5) = [character(len=9) :: 'table', &
                                                    'half_sine', 'step', 'chirp', 'spin_up']
    !> names of a history's parameters, by index
    character(len=*), parameter :: HIST_PARAM_NAMES(2) = [character(len=9) :: 'amplitude', &
                                                          'duration']

    !> Layout of one history as a column of reals (the binding's ld_spec):
    !! target, kind, amplitude, t0, duration, f0, f1, first table row, rows.
    integer, parameter :: LD_NSPEC = 9

    !> A scalar history g(t).
    type :: load_history_t
        integer :: kind = HIST_STEP
        real(dp) :: amplitude = 0.0_dp   !< A (a table's scale)
        real(dp) :: t0 = 0.0_dp          !< start (s)
        real(dp) :: duration = 0.0_dp    !< T (s): half-sine, chirp
        real(dp) :: f0 = 0.0_dp, f1 = 0.0_dp   !< chirp frequencies (Hz)
        real(dp), allocatable :: times(:), values(:)   !< table rows
    end type load_history_t

    !> A history applied at the tip (the free indices of its unknowns).
    type, extends(forcing_t) :: tip_history_t
        integer :: target = TARGET_FY
        type(load_history_t) :: hist
        integer :: iw = 0, iu = 0, idw = 0, idu = 0
        character(len=32) :: name = ''
    contains
        procedure :: apply => tip_apply
        procedure :: jacobian => tip_jacobian
        procedure :: work_name => tip_work_name
        procedure :: nparams => tip_nparams
        procedure :: param_name => tip_param_name
        procedure :: dforce => tip_dforce
        procedure :: breakpoints => tip_breakpoints
        procedure :: dbreak => tip_dbreak
    end type tip_history_t

contains

    !> g(t) (right-continuous).
    pure real(dp) function history_value(h, t) result(g)
        type(load_history_t), intent(in) :: h
        real(dp), intent(in) :: t
        g = h%amplitude*shape_value(h, t, h%duration)
    end function history_value

    !> dg/dp_i at t (i = 1 amplitude or scale, 2 duration).
    pure real(dp) function history_dvalue(h, i, t) result(dg)
        type(load_history_t), intent(in) :: h
        integer, intent(in) :: i
        real(dp), intent(in) :: t
        real(dp) :: s
        dg = 0.0_dp
        if (i == 1) then
            dg = shape_value(h, t, h%duration)
        else if (i == 2 .and. h%kind == HIST_HALF_SINE) then
            s = t - h%t0
            if (s >= 0.0_dp .and. s < h%duration) &
                dg = -h%amplitude*cos(pi*s/h%duration)*pi*s/h%duration**2
        end if
    end function history_dvalue

    !> Number of parameters of a history (amplitude; the half-sine's duration;
    !! the step's start, where it jumps).
    pure integer function history_nparams(h) result(np)
        type(load_history_t), intent(in) :: h
        np = 1
        if (h%kind == HIST_HALF_SINE .or. h%kind == HIST_STEP) np = 2
    end function history_nparams

    !> The times where g is not smooth, in (t0, t1].
    pure function history_breaks(h, t0, t1) result(tb)
        type(load_history_t), intent(in) :: h
        real(dp), intent(in) :: t0, t1
        real(dp), allocatable :: tb(:)
        select case (h%kind)
        case (HIST_TABLE)
            tb = h%times
        case (HIST_STEP)
            tb = [h%t0]
        case default
            tb = [h%t0, h%t0 + h%duration]
        end select
        tb = pack(tb, tb > t0 .and. tb <= t1)
    end function history_breaks

    !> The history's shape at t (amplitude 1), with duration dur.
    pure real(dp) function shape_value(h, t, dur) result(g)
        type(load_history_t), intent(in) :: h
        real(dp), intent(in) :: t, dur
        real(dp) :: s, w
        integer :: lo, hi, mid, n
        g = 0.0_dp
        s = t - h%t0
        select case (h%kind)
        case (HIST_STEP)
            if (s >= 0.0_dp) g = 1.0_dp
        case (HIST_HALF_SINE)
            if (s >= 0.0_dp .and. s < dur) g = sin(pi*s/dur)
        case (HIST_CHIRP)
            if (s >= 0.0_dp .and. s < dur) &
                g = sin(2.0_dp*pi*(h%f0*s + 0.5_dp*(h%f1 - h%f0)*s*s/dur))
        case (HIST_TABLE)
            n = size(h%times)
            if (t <= h%times(1)) then
                g = h%values(1)
            else if (t >= h%times(n)) then
                g = h%values(n)
            else
                ! bisection: times(lo) <= t < times(hi)
                lo = 1
                hi = n
                do while (hi - lo > 1)
                    mid = (lo + hi)/2
                    if (h%times(mid) <= t) then
                        lo = mid
                    else
                        hi = mid
                    end if
                end do
                w = (t - h%times(lo))/(h%times(hi) - h%times(lo))
                g = (1.0_dp - w)*h%values(lo) + w*h%values(hi)
            end if
        end select
    end function shape_value

    !> The generalized force of a unit history at q (the target's direction).
    pure subroutine unit_force(self, q, idx, e)
        class(tip_history_t), intent(in) :: self
        real(dp), intent(in) :: q(:)
        integer, intent(out) :: idx(2)
        real(dp), intent(out) :: e(2)
        real(dp) :: x, y, r2
        select case (self%target)
        case (TARGET_FX)
            idx = [self%iu, 0]
            e = [1.0_dp, 0.0_dp]
        case (TARGET_FY)
            idx = [self%iw, 0]
            e = [1.0_dp, 0.0_dp]
        case default
            x = 1.0_dp + q(self%idu)
            y = q(self%idw)
            r2 = 1.0_dp
            if (self%target == TARGET_TORQUE) r2 = x*x + y*y
            idx = [self%idw, self%idu]
            e = [x/r2, -y/r2]
        end select
    end subroutine unit_force

    pure subroutine tip_apply(self, t, q, v, f, power)
        class(tip_history_t), intent(in) :: self
        real(dp), intent(in) :: t, q(:), v(:)
        real(dp), intent(inout) :: f(:)
        real(dp), intent(out) :: power
        real(dp) :: g, e(2)
        integer :: idx(2), a
        g = history_value(self%hist, t)
        call unit_force(self, q, idx, e)
        power = 0.0_dp
        do a = 1, 2
            if (idx(a) == 0) cycle
            f(idx(a)) = f(idx(a)) + g*e(a)
            power = power + g*e(a)*v(idx(a))
        end do
    end subroutine tip_apply

    !> kb -= dF/dq: only a torque's direction depends on q (the Hessian of psi
    !! for the exact moment, the constant skew pair of Eq. 151 for the motor).
    pure subroutine tip_jacobian(self, t, q, v, kl, ku, kb, cb)
        class(tip_history_t), intent(in) :: self
        real(dp), intent(in) :: t, q(:), v(:)
        integer, intent(in) :: kl, ku
        real(dp), intent(inout) :: kb(:, :)
        real(dp), intent(inout), optional :: cb(:, :)
        real(dp) :: g, x, y, r2
        if (self%target /= TARGET_TORQUE .and. self%target /= TARGET_MOTOR) return
        g = history_value(self%hist, t)
        if (g == 0.0_dp) return
        x = 1.0_dp + q(self%idu)
        y = q(self%idw)
        if (self%target == TARGET_TORQUE) then
            r2 = x*x + y*y
            call band_add(kb, kl, ku, self%idw, self%idw, g*2.0_dp*x*y/r2**2)
            call band_add(kb, kl, ku, self%idu, self%idu, -g*2.0_dp*x*y/r2**2)
            call band_add(kb, kl, ku, self%idw, self%idu, -g*(y*y - x*x)/r2**2)
            call band_add(kb, kl, ku, self%idu, self%idw, -g*(y*y - x*x)/r2**2)
        else
            call band_add(kb, kl, ku, self%idw, self%idu, -g)
            call band_add(kb, kl, ku, self%idu, self%idw, g)
        end if
    end subroutine tip_jacobian

    pure function tip_work_name(self) result(name)
        class(tip_history_t), intent(in) :: self
        character(len=:), allocatable :: name
        name = trim(self%name)
        if (len(name) == 0) name = trim(TARGET_NAMES(self%target))
    end function tip_work_name

    pure integer function tip_nparams(self) result(np)
        class(tip_history_t), intent(in) :: self
        np = history_nparams(self%hist)
    end function tip_nparams

    pure function tip_param_name(self, i) result(name)
        class(tip_history_t), intent(in) :: self
        integer, intent(in) :: i
        character(len=:), allocatable :: name
        if (self%hist%kind == HIST_STEP .and. i == 2) then
            name = self%work_name()//'_start'
        else
            name = self%work_name()//'_'//trim(HIST_PARAM_NAMES(i))
        end if
    end function tip_param_name

    !> The step's start moves its jump: d tb/d start = 1 there.
    pure real(dp) function tip_dbreak(self, i, tb) result(d)
        class(tip_history_t), intent(in) :: self
        integer, intent(in) :: i
        real(dp), intent(in) :: tb
        d = 0.0_dp
        if (self%hist%kind == HIST_STEP .and. i == 2 .and. tb == self%hist%t0) d = 1.0_dp
    end function tip_dbreak

    pure subroutine tip_dforce(self, i, t, q, v, fp)
        class(tip_history_t), intent(in) :: self
        integer, intent(in) :: i
        real(dp), intent(in) :: t, q(:), v(:)
        real(dp), intent(inout) :: fp(:)
        real(dp) :: dg, e(2)
        integer :: idx(2), a
        dg = history_dvalue(self%hist, i, t)
        call unit_force(self, q, idx, e)
        do a = 1, 2
            if (idx(a) /= 0) fp(idx(a)) = fp(idx(a)) + dg*e(a)
        end do
    end subroutine tip_dforce

    pure function tip_breakpoints(self, t0, t1) result(tb)
        class(tip_history_t), intent(in) :: self
        real(dp), intent(in) :: t0, t1
        real(dp), allocatable :: tb(:)
        tb = history_breaks(self%hist, t0, t1)
    end function tip_breakpoints

    !> The histories of columns spec(LD_NSPEC, :) and table rows tab(2, :)
    !! (t, value), named by their targets (tip_fy, tip_fy_2, ...). The tip
    !! indices are set by the caller (release_response).
    !! A column with target TARGET_HUB is the hub's spin-up law (amplitude
    !! w_s, duration T): returned in hub(1:2) = [w_s, T], has_hub.
    !! A hub column of kind HIST_TABLE gives the hub angle as a table: its rows
    !! in hub_tab (2, rows), its scale in hub(1).
    subroutine histories_from_columns(spec, tab, hists, stat, hub, has_hub, hub_tab)
        real(dp), intent(in) :: spec(:, :), tab(:, :)
        type(tip_history_t), allocatable, intent(out) :: hists(:)
        type(status_t), intent(inout) :: stat
        real(dp), intent(out), optional :: hub(2)
        logical, intent(out), optional :: has_hub
        real(dp), allocatable, intent(out), optional :: hub_tab(:, :)
        integer :: l, tg, kd, r0, nr, same, nh, m
        nh = count(nint(spec(1, :)) == TARGET_HUB)
        if (present(has_hub)) has_hub = nh > 0
        if (present(hub)) hub = 0.0_dp
        if (nh > 1) then
            call set_status(stat, ERR_INPUT, 'load histories', fmt_int(nh)// &
                            ' hub laws given, expected at most one')
            return
        end if
        allocate (hists(size(spec, 2) - nh))
        m = 0
        do l = 1, size(spec, 2)
            tg = nint(spec(1, l))
            kd = nint(spec(2, l))
            if (tg == TARGET_HUB) then
                if (present(hub)) hub = [spec(3, l), spec(5, l)]
                if (kd == HIST_TABLE .and. present(hub_tab)) then
                    r0 = nint(spec(8, l))
                    nr = nint(spec(9, l))
                    if (r0 < 1 .or. nr < 1 .or. r0 + nr - 1 > size(tab, 2)) then
                        call set_status(stat, ERR_INPUT, 'load histories', 'hub table rows '// &
                                        fmt_int(r0)//'..'//fmt_int(r0 + nr - 1)// &
                                        ' outside the '//fmt_int(size(tab, 2))//' rows given')
                        return
                    end if
                    hub_tab = tab(:, r0:r0 + nr - 1)
                end if
                cycle
            end if
            m = m + 1
            if (tg < 1 .or. tg > TARGET_MOTOR) then
                call set_status(stat, ERR_INPUT, 'load histories', 'history '//fmt_int(l)// &
                                ': target = '//fmt_int(tg)//', expected 1..5 (tip_fx, '// &
                                'tip_fy, tip_torque, motor_open, hub)')
                return
            end if
            if (kd < 1 .or. kd > HIST_CHIRP) then
                call set_status(stat, ERR_INPUT, 'load histories', 'history '//fmt_int(l)// &
                                ': kind = '//fmt_int(kd)//', expected 1..4 (table, '// &
                                'half_sine, step, chirp)')
                return
            end if
            hists(m)%target = tg
            hists(m)%hist%kind = kd
            hists(m)%hist%amplitude = spec(3, l)
            hists(m)%hist%t0 = spec(4, l)
            hists(m)%hist%duration = spec(5, l)
            hists(m)%hist%f0 = spec(6, l)
            hists(m)%hist%f1 = spec(7, l)
            if (kd == HIST_TABLE) then
                r0 = nint(spec(8, l))
                nr = nint(spec(9, l))
                if (r0 < 1 .or. nr < 1 .or. r0 + nr - 1 > size(tab, 2)) then
                    call set_status(stat, ERR_INPUT, 'load histories', 'history '// &
                                    fmt_int(l)//': table rows '//fmt_int(r0)//'..'// &
                                    fmt_int(r0 + nr - 1)//' outside the '// &
                                    fmt_int(size(tab, 2))//' rows given')
                    return
                end if
                hists(m)%hist%times = tab(1, r0:r0 + nr - 1)
                hists(m)%hist%values = tab(2, r0:r0 + nr - 1)
            end if
            same = count(hists(1:m - 1)%target == tg)
            hists(m)%name = trim(TARGET_NAMES(tg))
            if (same > 0) hists(m)%name = trim(TARGET_NAMES(tg))//'_'//fmt_int(same + 1)
        end do
    end subroutine histories_from_columns

    !> Check a history against an experiment ending at t_end; `label` names it
    !! in the message (the deck and field, or the API argument).
    subroutine history_check(h, label, t_end, stat)
        type(load_history_t), intent(in) :: h
        character(len=*), intent(in) :: label
        real(dp), intent(in) :: t_end
        type(status_t), intent(inout) :: stat
        real(dp) :: start
        integer :: i
        if (.not. ieee_is_finite(h%amplitude) .or. .not. ieee_is_finite(h%t0)) then
            call set_status(stat, ERR_INPUT, label, 'amplitude = '//fmt_real(h%amplitude)// &
                            ', start = '//fmt_real(h%t0)//': expected finite numbers')
            return
        end if
        start = h%t0
        select case (h%kind)
        case (HIST_TABLE)
            if (size(h%times) < 1) then
                call set_status(stat, ERR_INPUT, label, 'the table has no rows')
                return
            end if
            do i = 1, size(h%times)
                if (.not. (ieee_is_finite(h%times(i)) .and. ieee_is_finite(h%values(i)))) then
                    call set_status(stat, ERR_INPUT, label, 'row '//fmt_int(i)//': t = '// &
                                    fmt_real(h%times(i))//', value = '// &
                                    fmt_real(h%values(i))//', expected finite numbers')
                    return
                end if
                if (i > 1) then
                    if (.not. h%times(i) > h%times(i - 1)) then
                        call set_status(stat, ERR_INPUT, label, 'row '//fmt_int(i)// &
                                        ': t = '//fmt_real(h%times(i))//' is not after row '// &
                                        fmt_int(i - 1)//"'s t = "//fmt_real(h%times(i - 1))// &
                                        ' (times must increase)')
                        return
                    end if
                end if
            end do
            start = h%times(1)
        case (HIST_HALF_SINE, HIST_CHIRP)
            if (.not. (h%duration > 0.0_dp .and. ieee_is_finite(h%duration))) then
                call set_status(stat, ERR_INPUT, label, 'duration = '//fmt_real(h%duration)// &
                                ' s, expected a positive number')
                return
            end if
            if (h%kind == HIST_CHIRP .and. .not. (h%f0 >= 0.0_dp .and. h%f1 >= 0.0_dp .and. &
                                                  ieee_is_finite(h%f0) .and. &
                                                  ieee_is_finite(h%f1))) then
                call set_status(stat, ERR_INPUT, label, 'f0 = '//fmt_real(h%f0)//', f1 = '// &
                                fmt_real(h%f1)//' Hz, expected finite numbers >= 0')
                return
            end if
        end select
        if (start > t_end) then
            call set_status(stat, ERR_INPUT, label, 'starts at t = '//fmt_real(start)// &
                            ' s, after the experiment (last output time '// &
                            fmt_real(t_end)//' s)')
        end if
    end subroutine history_check

end module beamid_loads
