!> A prescribed hub rotation at the shoulder (issue 28): the arm's equations
!! written in the hub frame, which turns with the hub angle theta(t) (Omega =
!! theta'). With positions rho = (s + u, w) in that frame and J the +90 degree
!! rotation, the inertial acceleration is R(theta) [rho'' + 2 Omega J rho' +
!! Omega' J rho - Omega^2 rho], so the hub-frame equations gain the forces
!!
!!     F_hub = -int rho_A (2 Omega J rho' + Omega' J rho - Omega^2 rho) ds
!!           = Omega^2 (c + M q) - Omega' P (c + M q) - 2 Omega P M v
!!
!! with the consistent mass M (point masses included; it couples u with u and
!! w with w alike, so M P = P M), P the +90 degree turn of the nodal unknowns
!! ((P x)_u = -x_w, (P x)_w = x_u, slopes alike) and c = M X the mass-weighted
!! undeformed positions (X: u = s, u' = 1 at every node, including the clamped
!! root's slope). They are linear in the state; the geometrically nonlinear
!! element stiffens the arm under the centrifugal axial force by itself, so any
!! number of hub turns is exact while the deflection stays in the element's
!! range. The Coriolis force does no work (P M is skew), so the hub's work line
!! is the work of the centrifugal and angular-acceleration forces on the motion
!! relative to the hub, and the ledger of the relative energy closes with it.
!!
!! Hub law: the spin-up theta(t) = (w_s/T) [t^2/2 + (T/(2 pi))^2 (cos(2 pi t/T)
!! - 1)] for t <= T, then w_s (t - T/2) (Omega rises smoothly from 0 to w_s,
!! Omega' = (w_s/T)(1 - cos(2 pi t/T))). Its parameter: 1 w_s.
!! Needs a clamped root and no rotary inertia of the mass points.
module beamid_hub
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use beamid_kinds, only: dp, pi
    use beamid_status, only: status_t, set_status, ERR_INPUT, fmt_real, fmt_int
    use beamid_band, only: band_add, band_scatter
    use beamid_forcing, only: forcing_t
    use beamid_fe_element, only: FE_NDOF, FE_U, FE_W, fe_element_mass
    use beamid_fe_assembly, only: fe_mesh_t, fe_expand, DOF_W, DOF_U, DOF_DU
    use beamid_dynamics, only: dyn_system_t
    use beamid_loads, only: TARGET_NAMES, TARGET_HUB
    implicit none
    private

    public :: hub_forcing_t, hub_setup, hub_rate, hub_work_label, hub_param_label

    !> The hub's parameter (sensitivities, wrt): w_s of the spin-up law, or
    !! the scale of an angle table.
    character(len=*), parameter :: HUB_PARAM_NAMES(2) = [character(len=9) :: 'hub_speed', &
                                                         'hub_scale']

    type, extends(forcing_t) :: hub_forcing_t
        real(dp) :: ws = 0.0_dp, period = 1.0_dp   !< w_s (rad/s), T (s)
        type(fe_mesh_t) :: mesh
        real(dp), allocatable :: me(:, :, :)   !< element mass matrices (8, 8, nel)
        real(dp), allocatable :: xfull(:)      !< X on all unknowns (u = s, u' = 1)
        !> the hub angle as a table instead of the law: knots, angles (rad) and
        !! the natural cubic spline's second derivatives (ws is then the
        !! angles' scale)
        real(dp), allocatable :: tt(:), th(:), m2(:)
    contains
        procedure :: apply => hub_apply
        procedure :: jacobian => hub_jacobian
        procedure :: work_name => hub_work_name
        procedure :: velocity_coupled => hub_coupled
        procedure :: nparams => hub_nparams
        procedure :: param_name => hub_param_name
        procedure :: dforce => hub_dforce
        procedure :: dmass => hub_dmass
        procedure :: breakpoints => hub_breakpoints
        procedure :: rate => hub_rate_of
    end type hub_forcing_t

contains

    !> Omega and Omega' of the spin-up law at t.
    pure subroutine hub_rate(ws, period, t, om, omd)
        real(dp), intent(in) :: ws, period, t
        real(dp), intent(out) :: om, omd
        if (t <= 0.0_dp) then
            om = 0.0_dp
            omd = 0.0_dp
        else if (t < period) then
            om = (ws/period)*(t - period/(2.0_dp*pi)*sin(2.0_dp*pi*t/period))
            omd = (ws/period)*(1.0_dp - cos(2.0_dp*pi*t/period))
        else
            om = ws
            omd = 0.0_dp
        end if
    end subroutine hub_rate

    !> Omega, Omega' of this hub at t: the spin-up law, or the table's spline
    !! (linear beyond its ends), both times the scale ws for a table.
    pure subroutine hub_rate_of(self, t, om, omd)
        class(hub_forcing_t), intent(in) :: self
        real(dp), intent(in) :: t
        real(dp), intent(out) :: om, omd
        real(dp) :: h, a, b
        integer :: n, lo, hi, mid
        if (.not. allocated(self%tt)) then
            call hub_rate(self%ws, self%period, t, om, omd)
            return
        end if
        n = size(self%tt)
        if (t <= self%tt(1) .or. t >= self%tt(n)) then
            lo = merge(1, n - 1, t <= self%tt(1))
            h = self%tt(lo + 1) - self%tt(lo)
            ! the end slopes of the natural spline (zero curvature there)
            if (lo == 1) then
                om = (self%th(2) - self%th(1))/h - h*(2.0_dp*self%m2(1) + self%m2(2))/6.0_dp
            else
                om = (self%th(n) - self%th(n - 1))/h + h*(self%m2(n - 1) + 2.0_dp*self%m2(n))/6.0_dp
            end if
            om = self%ws*om
            omd = 0.0_dp
            return
        end if
        lo = 1
        hi = n
        do while (hi - lo > 1)
            mid = (lo + hi)/2
            if (self%tt(mid) <= t) then
                lo = mid
            else
                hi = mid
            end if
        end do
        h = self%tt(hi) - self%tt(lo)
        a = (self%tt(hi) - t)/h
        b = (t - self%tt(lo))/h
        om = (self%th(hi) - self%th(lo))/h + h*(-(3.0_dp*a*a - 1.0_dp)*self%m2(lo) &
                                                 + (3.0_dp*b*b - 1.0_dp)*self%m2(hi))/6.0_dp
        omd = a*self%m2(lo) + b*self%m2(hi)
        om = self%ws*om
        omd = self%ws*omd
    end subroutine hub_rate_of

    !> Natural cubic spline second derivatives through (t, y) (t increasing).
    pure function spline_m2(t, y) result(m2)
        real(dp), intent(in) :: t(:), y(:)
        real(dp) :: m2(size(t)), c(size(t)), d(size(t)), w
        integer :: n, i
        n = size(t)
        m2 = 0.0_dp
        if (n < 3) return
        ! tridiagonal (Thomas) for the interior knots, m2(1) = m2(n) = 0
        c = 0.0_dp
        d = 0.0_dp
        do i = 2, n - 1
            w = 2.0_dp*(t(i + 1) - t(i - 1)) - (t(i) - t(i - 1))*c(i - 1)
            c(i) = (t(i + 1) - t(i))/w
            d(i) = (6.0_dp*((y(i + 1) - y(i))/(t(i + 1) - t(i)) - (y(i) - y(i - 1))/ &
                            (t(i) - t(i - 1))) - (t(i) - t(i - 1))*d(i - 1))/w
        end do
        do i = n - 1, 2, -1
            m2(i) = d(i) - c(i)*m2(i + 1)
        end do
    end function spline_m2

    !> The hub forcing of sys under the spin-up law (w_s, T), or with
    !! `times`, `angles` the hub angle as a table (a natural cubic spline,
    !! scaled by ws); `label` names the input in messages.
    subroutine hub_setup(sys, ws, period, label, hub, stat, times, angles)
        type(dyn_system_t), intent(in) :: sys
        real(dp), intent(in) :: ws, period
        character(len=*), intent(in) :: label
        type(hub_forcing_t), intent(out) :: hub
        type(status_t), intent(inout) :: stat
        real(dp), intent(in), optional :: times(:), angles(:)
        integer :: el, nd, i
        if (present(times)) then
            if (size(times) < 2 .or. size(times) /= size(angles)) then
                call set_status(stat, ERR_INPUT, label, 'the hub angle table needs at '// &
                                'least 2 rows of (t, angle)')
                return
            end if
            do i = 2, size(times)
                if (.not. times(i) > times(i - 1)) then
                    call set_status(stat, ERR_INPUT, label, 'row '//fmt_int(i)//': t = '// &
                                    fmt_real(times(i))//' is not after row '// &
                                    fmt_int(i - 1)//"'s t = "//fmt_real(times(i - 1))// &
                                    ' (times must increase)')
                    return
                end if
            end do
            hub%tt = times
            hub%th = angles
            hub%m2 = spline_m2(times, angles)
        else if (.not. (period > 0.0_dp .and. ieee_is_finite(period))) then
            call set_status(stat, ERR_INPUT, label, 'T = '//fmt_real(period)// &
                            ' s, expected a positive spin-up time')
            return
        end if
        if (.not. ieee_is_finite(ws)) then
            call set_status(stat, ERR_INPUT, label, 'w_s = '//fmt_real(ws)// &
                            ' rad/s, expected a finite number')
            return
        end if
        if (sys%rotary .or. sys%mesh%root_flex /= 0.0_dp .or. sys%mesh%nhinge > 0) then
            call set_status(stat, ERR_INPUT, label, 'a hub rotation needs a clamped root '// &
                            '(root_flex = 0), locked joints and no rotary inertia of the '// &
                            'mass points (J_elbow = J_tip = 0)')
            return
        end if
        hub%ws = ws
        hub%period = period
        hub%mesh = sys%mesh
        allocate (hub%me(FE_NDOF, FE_NDOF, sys%mesh%nel), hub%xfull(sys%mesh%ndof))
        do el = 1, sys%mesh%nel
            call fe_element_mass(sys%mesh%h(el), sys%mesh%rho(el), hub%me(:, :, el))
        end do
        hub%xfull = 0.0_dp
        do nd = 1, sys%mesh%nnode
            hub%xfull(sys%mesh%node_dof(DOF_U, nd)) = sys%mesh%s(nd)
            hub%xfull(sys%mesh%node_dof(DOF_DU, nd)) = 1.0_dp
        end do
    end subroutine hub_setup

    !> Element vector x <- P x (P turns (u, w) by +90 degrees: (P x)_u = -x_w,
    !! (P x)_w = x_u, slopes alike).
    pure function turn(x) result(y)
        real(dp), intent(in) :: x(FE_NDOF)
        real(dp) :: y(FE_NDOF)
        y(FE_U) = -x(FE_W)
        y(FE_W) = x(FE_U)
    end function turn

    !> F_hub = a (c + M q) + b P (c + M q) + g P M v, scattered to the free
    !! unknowns (a = Omega^2, b = -Omega', g = -2 Omega; their w_s derivatives
    !! for dforce), element by element, the point masses on (u, w).
    pure subroutine hub_force(self, a, b, g, q, v, f, we, wn)
        class(hub_forcing_t), intent(in) :: self
        real(dp), intent(in) :: a, b, g, q(:), v(:)
        real(dp), intent(inout) :: f(:)
        !> weights of the elements' and the nodes' masses (absent: 1): the
        !! derivative with respect to a mass parameter
        real(dp), intent(in), optional :: we(:), wn(:)
        real(dp) :: zf(self%mesh%ndof), vf(self%mesh%ndof), ze(FE_NDOF), ve(FE_NDOF)
        real(dp) :: fe(FE_NDOF), mz(FE_NDOF), mv(FE_NDOF), m, zu, zw, vu, vw
        integer :: el, k, i, nd, iu, iw
        associate (mesh => self%mesh)
            call fe_expand(mesh, q, zf)
            zf = zf + self%xfull
            call fe_expand(mesh, v, vf)
            do el = 1, mesh%nel
                ze = zf(mesh%el_dof(:, el))
                ve = vf(mesh%el_dof(:, el))
                mz = matmul(self%me(:, :, el), ze)
                mv = matmul(self%me(:, :, el), ve)
                fe = a*mz + b*turn(mz) + g*turn(mv)
                if (present(we)) fe = we(el)*fe
                do k = 1, FE_NDOF
                    i = mesh%el_free(k, el)
                    if (i /= 0) f(i) = f(i) + fe(k)
                end do
            end do
            do nd = 2, mesh%nnode
                m = mesh%node_mass(nd)
                if (present(wn)) m = wn(nd)
                if (m == 0.0_dp) cycle
                iu = mesh%free_of(mesh%node_dof(DOF_U, nd))
                iw = mesh%free_of(mesh%node_dof(DOF_W, nd))
                zu = zf(mesh%node_dof(DOF_U, nd))
                zw = zf(mesh%node_dof(DOF_W, nd))
                vu = vf(mesh%node_dof(DOF_U, nd))
                vw = vf(mesh%node_dof(DOF_W, nd))
                f(iu) = f(iu) + m*(a*zu - b*zw - g*vw)
                f(iw) = f(iw) + m*(a*zw + b*zu + g*vu)
            end do
        end associate
    end subroutine hub_force

    pure subroutine hub_apply(self, t, q, v, f, power)
        class(hub_forcing_t), intent(in) :: self
        real(dp), intent(in) :: t, q(:), v(:)
        real(dp), intent(inout) :: f(:)
        real(dp), intent(out) :: power
        real(dp) :: om, omd, fh(size(q))
        call self%rate(t, om, omd)
        power = 0.0_dp
        if (om == 0.0_dp .and. omd == 0.0_dp) return
        fh = 0.0_dp
        call hub_force(self, om*om, -omd, -2.0_dp*om, q, v, fh)
        f = f + fh
        power = dot_product(fh, v)
    end subroutine hub_apply

    !> kb -= dF/dq = Omega^2 M - Omega' P M; cb -= dF/dv = -2 Omega P M.
    pure subroutine hub_jacobian(self, t, q, v, kl, ku, kb, cb)
        class(hub_forcing_t), intent(in) :: self
        real(dp), intent(in) :: t, q(:), v(:)
        integer, intent(in) :: kl, ku
        real(dp), intent(inout) :: kb(:, :)
        real(dp), intent(inout), optional :: cb(:, :)
        real(dp) :: om, omd, pm(FE_NDOF, FE_NDOF), m
        integer :: el, j, nd, iu, iw
        call self%rate(t, om, omd)
        if (om == 0.0_dp .and. omd == 0.0_dp) return
        associate (mesh => self%mesh)
            do el = 1, mesh%nel
                do j = 1, FE_NDOF
                    pm(:, j) = turn(self%me(:, j, el))
                end do
                call band_scatter(kb, kl, ku, mesh%el_free(:, el), &
                                  -om*om*self%me(:, :, el) + omd*pm)
                if (present(cb)) call band_scatter(cb, kl, ku, mesh%el_free(:, el), &
                                                   2.0_dp*om*pm)
            end do
            do nd = 2, mesh%nnode
                m = mesh%node_mass(nd)
                if (m == 0.0_dp) cycle
                iu = mesh%free_of(mesh%node_dof(DOF_U, nd))
                iw = mesh%free_of(mesh%node_dof(DOF_W, nd))
                call band_add(kb, kl, ku, iu, iu, -om*om*m)
                call band_add(kb, kl, ku, iw, iw, -om*om*m)
                ! P M on (u, w): row u gets -m x_w, row w gets m x_u
                call band_add(kb, kl, ku, iu, iw, -omd*m)
                call band_add(kb, kl, ku, iw, iu, omd*m)
                if (present(cb)) then
                    call band_add(cb, kl, ku, iu, iw, -2.0_dp*om*m)
                    call band_add(cb, kl, ku, iw, iu, 2.0_dp*om*m)
                end if
            end do
        end associate
    end subroutine hub_jacobian

    pure function hub_work_name(self) result(name)
        class(hub_forcing_t), intent(in) :: self
        character(len=:), allocatable :: name
        name = hub_work_label()
    end function hub_work_name

    !> The hub's work line in the ledger: its target's name (beamid_loads).
    pure function hub_work_label() result(name)
        character(len=:), allocatable :: name
        name = trim(TARGET_NAMES(TARGET_HUB))
    end function hub_work_label

    !> The name of the hub's parameter: of the angle table (`table`) or
    !! of the spin-up law.
    pure function hub_param_label(table) result(name)
        logical, intent(in) :: table
        character(len=:), allocatable :: name
        name = trim(HUB_PARAM_NAMES(merge(2, 1, table)))
    end function hub_param_label

    pure logical function hub_coupled(self) result(coupled)
        class(hub_forcing_t), intent(in) :: self
        coupled = .true.
    end function hub_coupled

    pure integer function hub_nparams(self) result(np)
        class(hub_forcing_t), intent(in) :: self
        np = 1
    end function hub_nparams

    pure function hub_param_name(self, i) result(name)
        class(hub_forcing_t), intent(in) :: self
        integer, intent(in) :: i
        character(len=:), allocatable :: name
        name = hub_param_label(allocated(self%tt))
    end function hub_param_name

    !> dF/dw_s: Omega and Omega' are proportional to w_s.
    pure subroutine hub_dforce(self, i, t, q, v, fp)
        class(hub_forcing_t), intent(in) :: self
        integer, intent(in) :: i
        real(dp), intent(in) :: t, q(:), v(:)
        real(dp), intent(inout) :: fp(:)
        real(dp) :: om, omd
        if (self%ws == 0.0_dp) return
        call self%rate(t, om, omd)
        call hub_force(self, 2.0_dp*om*om/self%ws, -omd/self%ws, -2.0_dp*om/self%ws, q, v, fp)
    end subroutine hub_dforce

    !> dF/dp of a mass parameter: F_hub is linear in the masses, so it is
    !! F_hub with the element masses of beam `beam` divided by their density
    !! (the others 0), or with the one point mass at free unknown iu_point.
    pure subroutine hub_dmass(self, beam, iu_point, t, q, v, fp)
        class(hub_forcing_t), intent(in) :: self
        integer, intent(in) :: beam, iu_point
        real(dp), intent(in) :: t, q(:), v(:)
        real(dp), intent(inout) :: fp(:)
        real(dp) :: om, omd, we(self%mesh%nel), wn(self%mesh%nnode)
        integer :: el, nd
        call self%rate(t, om, omd)
        if (om == 0.0_dp .and. omd == 0.0_dp) return
        we = 0.0_dp
        wn = 0.0_dp
        if (beam > 0) then
            do el = 1, self%mesh%nel
                if (self%mesh%beam(el) == beam .and. self%mesh%rho(el) /= 0.0_dp) &
                    we(el) = 1.0_dp/self%mesh%rho(el)
            end do
        else if (iu_point > 0) then
            do nd = 2, self%mesh%nnode
                if (self%mesh%free_of(self%mesh%node_dof(DOF_U, nd)) == iu_point) wn(nd) = 1.0_dp
            end do
        end if
        call hub_force(self, om*om, -omd, -2.0_dp*om, q, v, fp, we, wn)
    end subroutine hub_dmass

    pure function hub_breakpoints(self, t0, t1) result(tb)
        class(hub_forcing_t), intent(in) :: self
        real(dp), intent(in) :: t0, t1
        real(dp), allocatable :: tb(:)
        if (allocated(self%tt)) then
            tb = pack(self%tt, self%tt > t0 .and. self%tt <= t1)
        else
            tb = pack([self%period], [self%period > t0 .and. self%period <= t1])
        end if
    end function hub_breakpoints

end module beamid_hub
