!> f2py-facing API of the finite element dynamics (Chapter IV-V, forward).
!!
!! The model is (nbeams, nparams, params) in the layout of beamid_model, the
!! mesh elements_per_beam (nepb). State vectors have nstate = 2 nfree + nx
!! entries: q (free unknowns, the order of beamid_fe_assembly), v = q', and
!! the motor torque when the motor has a current-loop lag (nx = 1).
!! Methods: 0 RK4 (fixed dt), 1 implicit Radau IIA (rtol, atol; default
!! 1e-9). Friction laws: 0 sign (Eq. 101; in both integrators its switches
!! are events, with sticking; elsewhere sign(0) = 0), 1 smooth
!! v/sqrt(v^2 + vslip^2), 2 literal Fortran SIGN(1, v) (+1 at v = 0, no events).
!! Outputs of a failed call are zeros: f2py allocates output arrays zeroed and
!! declares output scalars = 0 (characters blank), so no entry zeroes them.
module beamid_api_dynamics
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, status_out, STATUS_OK, ERR_INPUT, set_status, fmt_int
    use beamid_model, only: chain_t, chain_from_vector
    use beamid_fe_element, only: fe_hermite
    use beamid_fe_assembly, only: fe_band_to_dense, fe_node_value, fe_load_t, &
                                  DOF_W, DOF_DW, DOF_U, DOF_DU, DOF_DW_OUT, DOF_DU_OUT
    ! ld_spec columns have beamid_loads LD_NSPEC = 9 entries (a literal for f2py)
    use beamid_loads, only: tip_history_t, histories_from_columns
    use beamid_hub, only: hub_work_label, hub_param_label
    use beamid_release, only: release_spec_t, release_out_t, release_response, NQTY, &
                              NLOAD, release_quantity_name, release_wrt_name
    use beamid_dynamics, only: dyn_system_t, dyn_setup, dyn_set_modes, dyn_cforces, &
                               dyn_cjacobian, dyn_cmass, dyn_nwork, dyn_work_name
    implicit none
    private

    public :: api_dyn_sizes, api_dyn_simulate_modal, api_dyn_system
    public :: api_dyn_profile, api_dyn_system_modal
    public :: api_dyn_release, api_dyn_quantity_name, api_dyn_wrt_name
    public :: api_work_names, api_dyn_load_names, api_dyn_forced

contains

    !> Names of the work lines of the ledger of a chain of nbeams beams (no
    !! forcing), space separated, in the order of the work vector (as
    !! api_param_names for the parameters).
    subroutine api_work_names(nbeams, names, code, message)
        integer(c_int), intent(in) :: nbeams
        character(len=4096), intent(out) :: names
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        character(len=:), allocatable :: joined
        type(status_t) :: stat
        integer :: i
        joined = ''
        names = ''
        if (nbeams < 1 .or. dyn_nwork(int(nbeams))*24 > len(names)) then
            call set_status(stat, ERR_INPUT, 'api_work_names', 'cannot name the work '// &
                            'lines of '//fmt_int(int(nbeams))//' beams')
        else
            do i = 1, dyn_nwork(int(nbeams))
                joined = joined//dyn_work_name(int(nbeams), i)//' '
            end do
            names = joined
        end if
        call status_out(stat, code, message)
    end subroutine api_work_names

    subroutine make_system(nbeams, nparams, params, nepb, gain, law, vslip, sys, stat)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, law
        real(c_double), intent(in) :: params(nparams), gain, vslip
        type(dyn_system_t), intent(out) :: sys
        type(status_t), intent(inout) :: stat
        type(chain_t) :: chain
        call chain_from_vector(int(nbeams), real(params, dp), chain, stat)
        if (stat%code /= STATUS_OK) return
        call dyn_setup(chain, int(nepb), real(gain, dp), int(law), real(vslip, dp), sys, stat)
    end subroutine make_system

    !> Sizes: free unknowns, state length and number of work lines.
    subroutine api_dyn_sizes(nbeams, nparams, params, nepb, gain, nfree, nstate, nwork, &
                             code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb
        real(c_double), intent(in) :: params(nparams), gain
        integer(c_int), intent(out) :: nfree, nstate, nwork, code
        character(len=256), intent(out) :: message
        type(dyn_system_t) :: sys
        type(status_t) :: stat
        call make_system(nbeams, nparams, params, nepb, gain, 0_c_int, 1.0_c_double, sys, stat)
        if (stat%code == STATUS_OK) then
            nfree = int(sys%n, c_int)
            nstate = int(sys%nstate, c_int)
            nwork = int(sys%nwork, c_int)
        end if
        call status_out(stat, code, message)
    end subroutine api_dyn_sizes

    !> A release: the static shape under loads (fx, fy, moment, moment form)
    !! held, released at t = 0 and integrated to t_out (beamid_release), on the full
    !! model or the truncated modal model (Eq. 127, Section 4.1.4)
    !! that keeps the linear modes `modes(1:nmodes)` (1-based indices into the
    !! ascending frequencies of api_fe_modes); nmodes = 0: the full model.
    !! The initial state is projected on the retained modes (eta = Phi^T M q);
    !! states are returned as physical q = Phi eta, v = Phi eta'.
    !! info = (steps, rejected, force evaluations, Jacobians, Newton iterations,
    !! friction events, steps cut or redone to land on one). events(:, k) for
    !! k <= min(info(6), maxev): time, component j = 2 (point - 1) + c (c = 1
    !! u, 2 w), kind (0 start, 1 velocity zero, 2 unstick), mode before and
    !! after (+-1 sliding, 0 sticking), friction force before and after (N).
    !! progress(1) is set to each output time as it is reached, while the call
    !! runs without Python's lock (threadsafe), so a caller can watch it.
    subroutine api_dyn_simulate_modal(nbeams, nparams, params, nepb, loads, gain, method, &
                                      law, vslip, dt, rtol, atol, h0, use_init, nstate, &
                                      y_init, nt, t_out, nwork, nmodes, modes, maxev, states, &
                                      tip, torque, ledger, work, info, events, progress, code, &
                                      message)
        !f2py threadsafe
        integer(c_int), intent(in) :: nbeams, nparams, nepb, method, law, use_init, nstate
        integer(c_int), intent(in) :: nt, nwork, nmodes, modes(nmodes), maxev
        real(c_double), intent(in) :: params(nparams), loads(4), gain, vslip, dt, rtol
        real(c_double), intent(in) :: atol, h0, y_init(nstate), t_out(nt)
        real(c_double), intent(out) :: states(nstate, nt), tip(3, nt), torque(nt)
        real(c_double), intent(out) :: ledger(4, nt), work(nwork, nt), events(7, maxev)
        real(c_double), intent(inout), target :: progress(1)
        integer(c_int), intent(out) :: info(7), code
        character(len=256), intent(out) :: message
        type(chain_t) :: chain
        type(status_t) :: stat
        type(release_spec_t) :: spec
        type(release_out_t) :: out
        integer :: nowrt(0)
        call chain_from_vector(int(nbeams), real(params, dp), chain, stat)
        if (stat%code == STATUS_OK .and. nmodes < 0) then
            call set_status(stat, ERR_INPUT, 'api_dyn_simulate_modal', 'nmodes = '// &
                            fmt_int(int(nmodes))//', expected >= 0')
        end if
        if (stat%code == STATUS_OK) then
            spec = release_spec(nepb, loads, gain, method, law, vslip, dt, rtol, atol, h0)
            spec%modes = int(modes(1:max(0, nmodes)))
            if (use_init /= 0) spec%y_init = real(y_init, dp)
            spec%progress => progress
            call release_response(chain, spec, real(t_out, dp), nowrt, out, stat)
        end if
        call copy_history(out, 'api_dyn_simulate_modal', nstate, nwork, states, tip, torque, &
                          ledger, work, info, events, stat)
        call status_out(stat, code, message)
    end subroutine api_dyn_simulate_modal

    !> The outputs both release entries share, after checking the caller's
    !! state and work sizes against the run's.
    subroutine copy_history(out, where, nstate, nwork, states, tip, torque, ledger, work, &
                            info, events, stat)
        type(release_out_t), intent(in) :: out
        character(len=*), intent(in) :: where
        integer(c_int), intent(in) :: nstate, nwork
        real(c_double), intent(inout) :: states(:, :), tip(:, :), torque(:), ledger(:, :)
        real(c_double), intent(inout) :: work(:, :), events(:, :)
        integer(c_int), intent(inout) :: info(7)
        type(status_t), intent(inout) :: stat
        if (stat%code /= STATUS_OK) return
        if (out%nstate /= nstate .or. out%nwork /= nwork) then
            call set_status(stat, ERR_INPUT, where, 'nstate = '//fmt_int(int(nstate))// &
                            ', nwork = '//fmt_int(int(nwork))//', expected '// &
                            fmt_int(out%nstate)//', '//fmt_int(out%nwork))
            return
        end if
        info = int([out%stats%steps, out%stats%rejected, out%stats%fevals, &
                    out%stats%jevals, out%stats%newton, out%hist%nevents, &
                    out%stats%event_steps], c_int)
        call copy_events(out, events)
        states = out%hist%y
        torque = out%hist%torque
        work = out%hist%work
        tip = out%tip
        ledger = out%ledger
    end subroutine copy_history

    !> The release spec of the binding's scalar arguments.
    type(release_spec_t) function release_spec(nepb, loads, gain, method, law, vslip, dt, rtol, &
                                               atol, h0) result(spec)
        integer(c_int), intent(in) :: nepb, method, law
        real(c_double), intent(in) :: loads(4), gain, vslip, dt, rtol, atol, h0
        spec = release_spec_t(elements_per_beam=int(nepb), load=fe_load_t(loads(1), loads(2), &
            loads(3), nint(loads(4))), motor_gain=gain, integrator=int(method), rtol=rtol, &
            atol=atol, dt=dt, h0=h0, friction=int(law), friction_velocity=vslip)
    end function release_spec

    !> Event records as columns (time, component, kind, mode before, after,
    !! force before, after), as many as fit.
    subroutine copy_events(out, events)
        type(release_out_t), intent(in) :: out
        real(c_double), intent(inout) :: events(:, :)
        integer :: k
        do k = 1, min(size(events, 2), out%hist%nevents)
            associate (ev => out%hist%events(k))
                events(:, k) = [ev%t, real(ev%comp, dp), real(ev%kind, dp), &
                                real(ev%before, dp), real(ev%after, dp), ev%force_before, &
                                ev%force_after]
            end associate
        end do
    end subroutine copy_events

    !> Generalized force F(q, v, x), work rates, torque, the Jacobians
    !! K = -dF/dq, C = -dF/dv (dense) and the motor-lag couplings b = dF/dT,
    !! p = dT'/dq, d = dT'/dv, e = dT'/dT, and M(q), for checks.
    subroutine api_dyn_system(nbeams, nparams, params, nepb, gain, law, vslip, nfree, nx, &
                              q, v, x, nwork, force, power, torque, kmat, cmat, mass, b, p, &
                              d, e, code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, law, nfree, nx, nwork
        real(c_double), intent(in) :: params(nparams), gain, vslip, q(nfree), v(nfree), x(1)
        real(c_double), intent(out) :: force(nfree), power(nwork), torque
        real(c_double), intent(out) :: kmat(nfree, nfree), cmat(nfree, nfree)
        real(c_double), intent(out) :: mass(nfree, nfree), b(nfree), p(nfree), d(nfree), e
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(dyn_system_t) :: sys
        type(status_t) :: stat
        call make_system(nbeams, nparams, params, nepb, gain, law, vslip, sys, stat)
        if (stat%code == STATUS_OK .and. (sys%n /= nfree .or. sys%nx /= nx .or. &
                                          sys%nwork /= nwork)) then
            call set_status(stat, ERR_INPUT, 'api_dyn_system', 'nfree, nx, nwork = '// &
                            fmt_int(int(nfree))//', '//fmt_int(int(nx))//', '// &
                            fmt_int(int(nwork))//', expected '//fmt_int(sys%n)//', '// &
                            fmt_int(sys%nx)//', '//fmt_int(sys%nwork))
        end if
        if (stat%code == STATUS_OK) call dense_system(sys, q, v, x, force, power, torque, kmat, &
                                                      cmat, mass, b, p, d, e)
        call status_out(stat, code, message)
    end subroutine api_dyn_system

    !> api_dyn_system in the coordinates of a truncated modal model (Eq. 127):
    !! F~ = Phi^T F(Phi eta, Phi eta'), K~ = -dF~/deta, C~ = -dF~/deta', the
    !! mass Phi^T M Phi and the projected motor-lag couplings, for checks.
    subroutine api_dyn_system_modal(nbeams, nparams, params, nepb, gain, law, vslip, nmodes, &
                                    modes, nx, eta, etad, x, nwork, force, power, kmat, cmat, &
                                    mass, b, p, d, e, code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, law, nmodes, nx, nwork
        integer(c_int), intent(in) :: modes(nmodes)
        real(c_double), intent(in) :: params(nparams), gain, vslip, eta(nmodes)
        real(c_double), intent(in) :: etad(nmodes), x(1)
        real(c_double), intent(out) :: force(nmodes), power(nwork)
        real(c_double), intent(out) :: kmat(nmodes, nmodes), cmat(nmodes, nmodes)
        real(c_double), intent(out) :: mass(nmodes, nmodes), b(nmodes), p(nmodes)
        real(c_double), intent(out) :: d(nmodes), e
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(dyn_system_t) :: sys
        type(status_t) :: stat
        real(c_double) :: torque
        call make_system(nbeams, nparams, params, nepb, gain, law, vslip, sys, stat)
        if (stat%code == STATUS_OK .and. (sys%nx /= nx .or. sys%nwork /= nwork)) then
            call set_status(stat, ERR_INPUT, 'api_dyn_system_modal', 'nx, nwork = '// &
                            fmt_int(int(nx))//', '//fmt_int(int(nwork))//', expected '// &
                            fmt_int(sys%nx)//', '//fmt_int(sys%nwork))
        end if
        if (stat%code == STATUS_OK) call dyn_set_modes(sys, int(modes), stat)
        if (stat%code == STATUS_OK) call dense_system(sys, eta, etad, x, force, power, torque, &
                                                      kmat, cmat, mass, b, p, d, e)
        call status_out(stat, code, message)
    end subroutine api_dyn_system_modal

    !> The outputs of api_dyn_system(_modal) at the coordinate state (c, c', x)
    !! of sys (full or modal).
    subroutine dense_system(sys, c, cd, x, force, power, torque, kmat, cmat, mass, b, p, d, e)
        type(dyn_system_t), intent(in) :: sys
        real(c_double), intent(in) :: c(:), cd(:), x(1)
        real(c_double), intent(out) :: force(:), power(:), torque, kmat(:, :), cmat(:, :)
        real(c_double), intent(out) :: mass(:, :), b(:), p(:), d(:), e
        real(dp), allocatable :: yc(:), kb(:, :), cb(:, :), mb(:, :)
        integer :: k, nb
        k = sys%nc
        nb = 2*sys%ckl + sys%cku + 1
        allocate (yc(sys%ncstate), kb(nb, k), cb(nb, k), mb(nb, k))
        yc(1:k) = c
        yc(k + 1:2*k) = cd
        if (sys%nx > 0) yc(2*k + 1) = x(1)
        ! the chain's own forces: no forcing in time is set up here (t = 0)
        call dyn_cforces(sys, 0.0_dp, yc, force, power, torque)
        call dyn_cjacobian(sys, 0.0_dp, yc, kb, cb, b, p, d, e)
        call fe_band_to_dense(kb, sys%ckl, sys%cku, kmat)
        call fe_band_to_dense(cb, sys%ckl, sys%cku, cmat)
        call dyn_cmass(sys, yc, mb)
        call fe_band_to_dense(mb, sys%ckl, sys%cku, mass)
    end subroutine dense_system

    !> Deformed shape x = s + u(s), y = w(s) at nsub points per element
    !! (Hermite interpolation of Eq. 76), npts = nel nsub + 1, plus the arc s.
    subroutine api_dyn_profile(nbeams, nparams, params, nepb, nfree, q, npts, s, x, y, &
                               code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, nfree, npts
        real(c_double), intent(in) :: params(nparams), q(nfree)
        real(c_double), intent(out) :: s(npts), x(npts), y(npts)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(dyn_system_t) :: sys
        type(status_t) :: stat
        real(dp) :: f(4), f1(4), f2(4), zeta, h, nw(4), nu(4)
        integer :: el, j, nsub, i
        call make_system(nbeams, nparams, params, nepb, 0.0_c_double, 0_c_int, 1.0_c_double, &
                         sys, stat)
        if (stat%code == STATUS_OK) then
            if (sys%n /= nfree .or. npts < sys%mesh%nel + 1 .or. &
                mod(npts - 1, sys%mesh%nel) /= 0) then
                call set_status(stat, ERR_INPUT, 'api_dyn_profile', 'nfree = '// &
                                fmt_int(int(nfree))//', npts = '//fmt_int(int(npts))// &
                                ': expected nfree = '//fmt_int(sys%n)// &
                                ' and npts = nel*nsub + 1 with nel = '//fmt_int(sys%mesh%nel))
            end if
        end if
        if (stat%code == STATUS_OK) then
            nsub = (npts - 1)/sys%mesh%nel
            i = 0
            do el = 1, sys%mesh%nel
                h = sys%mesh%h(el)
                ! the element's first node contributes its outboard slopes (a hinge's
                ! second pair; the node's own slopes elsewhere)
                nw = [fe_node_value(sys%mesh, q, el, DOF_W), &
                      fe_node_value(sys%mesh, q, el, DOF_DW_OUT), &
                      fe_node_value(sys%mesh, q, el + 1, DOF_W), &
                      fe_node_value(sys%mesh, q, el + 1, DOF_DW)]
                nu = [fe_node_value(sys%mesh, q, el, DOF_U), &
                      fe_node_value(sys%mesh, q, el, DOF_DU_OUT), &
                      fe_node_value(sys%mesh, q, el + 1, DOF_U), &
                      fe_node_value(sys%mesh, q, el + 1, DOF_DU)]
                do j = 0, nsub
                    if (j == 0 .and. el > 1) cycle
                    zeta = real(j, dp)/real(nsub, dp)
                    call fe_hermite(zeta, h, f, f1, f2)
                    i = i + 1
                    s(i) = sys%mesh%s(el) + zeta*h
                    x(i) = s(i) + dot_product(f, nu)
                    y(i) = dot_product(f, nw)
                end do
            end do
        end if
        call status_out(stat, code, message)
    end subroutine api_dyn_profile

    !> The quantity table of a release (beamid_release QTY_*): the name of
    !! quantity k and the number of quantities nq (k outside 1..nq: '').
    subroutine api_dyn_quantity_name(k, name, nq)
        integer(c_int), intent(in) :: k
        character(len=32), intent(out) :: name
        integer(c_int), intent(out) :: nq
        name = release_quantity_name(int(k))
        nq = int(NQTY, c_int)
    end subroutine api_dyn_quantity_name

    !> Name of sensitivity index `index` of a chain of nbeams beams (a
    !! parameter's, or load_fx, load_fy, load_moment after them) and the
    !! number of load components ncomp.
    subroutine api_dyn_wrt_name(nbeams, index, name, ncomp)
        integer(c_int), intent(in) :: nbeams, index
        character(len=32), intent(out) :: name
        integer(c_int), intent(out) :: ncomp
        name = release_wrt_name(int(nbeams), int(index))
        ncomp = int(NLOAD, c_int)
    end subroutine api_dyn_wrt_name

    !> A release (api_dyn_simulate_modal's arguments, full model) with the exported
    !! quantities y(nq, nt) (beamid_release QTY_*) and their sensitivities
    !! dy(nq, nt, nwrt) with respect to the parameters wrt (1-based indices
    !! into params, then nparams + 1..3: the load's fx, fy, moment), and the
    !! state sensitivities ds(nstate, nt, nwrt).
    subroutine api_dyn_release(nbeams, nparams, params, nepb, loads, gain, method, law, &
                               vslip, dt, rtol, atol, h0, nstate, nt, t_out, nwork, nwrt, wrt, &
                               nq, maxev, states, tip, torque, ledger, work, info, events, y, &
                               dy, ds, progress, code, message)
        !f2py threadsafe
        integer(c_int), intent(in) :: nbeams, nparams, nepb, method, law, nstate, nt, nwork
        integer(c_int), intent(in) :: nwrt, wrt(nwrt), nq, maxev
        real(c_double), intent(in) :: params(nparams), loads(4), gain, vslip, dt, rtol
        real(c_double), intent(in) :: atol, h0, t_out(nt)
        real(c_double), intent(out) :: states(nstate, nt), tip(3, nt), torque(nt)
        real(c_double), intent(out) :: ledger(4, nt), work(nwork, nt), events(7, maxev)
        real(c_double), intent(out) :: y(nq, nt), dy(nq, nt, nwrt), ds(nstate, nt, nwrt)
        real(c_double), intent(inout), target :: progress(1)
        integer(c_int), intent(out) :: info(7), code
        character(len=256), intent(out) :: message
        type(chain_t) :: chain
        type(status_t) :: stat
        type(release_spec_t) :: spec
        type(release_out_t) :: out
        call chain_from_vector(int(nbeams), real(params, dp), chain, stat)
        if (stat%code == STATUS_OK .and. nq /= NQTY) then
            call set_status(stat, ERR_INPUT, 'api_dyn_release', 'nq = '//fmt_int(int(nq))// &
                            ', expected '//fmt_int(NQTY))
        end if
        if (stat%code == STATUS_OK) then
            spec = release_spec(nepb, loads, gain, method, law, vslip, dt, rtol, atol, h0)
            spec%progress => progress
            call release_response(chain, spec, real(t_out, dp), int(wrt), out, stat)
        end if
        call copy_history(out, 'api_dyn_release', nstate, nwork, states, tip, torque, &
                          ledger, work, info, events, stat)
        if (stat%code == STATUS_OK) then
            y = out%y
            dy = out%dy
            ds = out%dstates
        end if
        call status_out(stat, code, message)
    end subroutine api_dyn_release

    !> Work-line names and parameter names of the load histories of columns
    !! ld_spec (LD_NSPEC x nld, beamid_loads) with table rows ld_tab, space
    !! separated (the ledger's lines after the chain's; the wrt names after
    !! the release load's).
    subroutine api_dyn_load_names(nld, ld_spec, ntab, ld_tab, works, pnames, code, message)
        integer(c_int), intent(in) :: nld, ntab
        real(c_double), intent(in) :: ld_spec(9, nld), ld_tab(2, ntab)
        character(len=4096), intent(out) :: works, pnames
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(tip_history_t), allocatable :: hists(:)
        type(status_t) :: stat
        character(len=:), allocatable :: jw, jp
        real(dp) :: hub(2)
        real(dp), allocatable :: hub_tab(:, :)
        logical :: has_hub
        integer :: l, i
        works = ''
        pnames = ''
        jw = ''
        jp = ''
        call histories_from_columns(real(ld_spec, dp), real(ld_tab, dp), hists, stat, hub, &
                                    has_hub, hub_tab)
        if (stat%code == STATUS_OK) then
            do l = 1, size(hists)
                jw = jw//hists(l)%work_name()//' '
                do i = 1, hists(l)%nparams()
                    jp = jp//hists(l)%param_name(i)//' '
                end do
            end do
            ! the hub after the histories (release_response's order)
            if (has_hub) then
                jw = jw//hub_work_label()//' '
                jp = jp//hub_param_label(allocated(hub_tab))//' '
            end if
            if (len(jw) > len(works) .or. len(jp) > len(pnames)) then
                call set_status(stat, ERR_INPUT, 'api_dyn_load_names', 'too many histories ('// &
                                fmt_int(int(nld))//') to name')
            else
                works = jw
                pnames = jp
            end if
        end if
        call status_out(stat, code, message)
    end subroutine api_dyn_load_names

    !> A dynamic experiment with load histories (beamid_loads): the release
    !! under `loads` (or from y_init when use_init /= 0), the histories of
    !! ld_spec/ld_tab acting at the tip from t = 0, sensitivities with respect
    !! to wrt (parameters, the release load's fx, fy, moment, then the
    !! histories' parameters; full model only), the truncated modal model with
    !! nmodes > 0. Outputs as api_dyn_release.
    subroutine api_dyn_forced(nbeams, nparams, params, nepb, loads, gain, method, law, vslip, &
                              dt, rtol, atol, h0, use_init, nstate, y_init, nt, t_out, nwork, &
                              nmodes, modes, nwrt, wrt, nq, maxev, nld, ld_spec, ntab, ld_tab, &
                              states, tip, torque, ledger, work, info, events, y, dy, ds, &
                              progress, code, message)
        !f2py threadsafe
        integer(c_int), intent(in) :: nbeams, nparams, nepb, method, law, use_init, nstate
        integer(c_int), intent(in) :: nt, nwork, nmodes, modes(nmodes), nwrt, wrt(nwrt), nq
        integer(c_int), intent(in) :: maxev, nld, ntab
        real(c_double), intent(in) :: params(nparams), loads(4), gain, vslip, dt, rtol
        real(c_double), intent(in) :: atol, h0, y_init(nstate), t_out(nt)
        real(c_double), intent(in) :: ld_spec(9, nld), ld_tab(2, ntab)
        real(c_double), intent(out) :: states(nstate, nt), tip(3, nt), torque(nt)
        real(c_double), intent(out) :: ledger(4, nt), work(nwork, nt), events(7, maxev)
        real(c_double), intent(out) :: y(nq, nt), dy(nq, nt, nwrt), ds(nstate, nt, nwrt)
        real(c_double), intent(inout), target :: progress(1)
        integer(c_int), intent(out) :: info(7), code
        character(len=256), intent(out) :: message
        type(chain_t) :: chain
        type(status_t) :: stat
        type(release_spec_t) :: spec
        type(release_out_t) :: out
        real(dp) :: hub(2)
        call chain_from_vector(int(nbeams), real(params, dp), chain, stat)
        if (stat%code == STATUS_OK .and. (nq /= NQTY .or. nmodes < 0)) then
            call set_status(stat, ERR_INPUT, 'api_dyn_forced', 'nq = '//fmt_int(int(nq))// &
                            ', nmodes = '//fmt_int(int(nmodes))//', expected '// &
                            fmt_int(NQTY)//' and >= 0')
        end if
        if (stat%code == STATUS_OK) then
            spec = release_spec(nepb, loads, gain, method, law, vslip, dt, rtol, atol, h0)
            spec%modes = int(modes(1:max(0, nmodes)))
            if (use_init /= 0) spec%y_init = real(y_init, dp)
            spec%progress => progress
            call histories_from_columns(real(ld_spec, dp), real(ld_tab, dp), &
                                        spec%histories, stat, hub, spec%hub, &
                                        spec%hub_table)
            spec%hub_ws = hub(1)
            spec%hub_period = hub(2)
        end if
        if (stat%code == STATUS_OK) &
            call release_response(chain, spec, real(t_out, dp), int(wrt), out, stat)
        call copy_history(out, 'api_dyn_forced', nstate, nwork, states, tip, torque, &
                          ledger, work, info, events, stat)
        if (stat%code == STATUS_OK) then
            y = out%y
            dy = out%dy
            ds = out%dstates
        end if
        call status_out(stat, code, message)
    end subroutine api_dyn_forced

end module beamid_api_dynamics
