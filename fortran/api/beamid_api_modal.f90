!> f2py binding of the modal analysis about a static equilibrium
!! (beamid_modal, issue 27): one call, its sizes from api_fe_mesh_sizes
!! (nfree, the model's mode count). The load is (fx, fy, moment,
!! moment_form) as in beamid_api_fe; stations are (kind SHAPE_*, beam, s).
module beamid_api_modal
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_status, only: status_t, STATUS_OK, status_out, set_status, ERR_INPUT, fmt_int
    use beamid_fe_assembly, only: fe_mesh_t
    use beamid_fe_nodes, only: fe_mesh_from_params, fe_load_from_values
    use beamid_modal, only: modal_spec_t, modal_out_t, modal_solve, modal_station, &
                            modal_station_sens, modal_check_stations
    implicit none
    private

    public :: api_modal

contains

    !> The first nmodes modes of the arm held by `load`: frequencies (Hz),
    !! damping ratios, damped (1 when the model has damping), the
    !! equilibrium q, the mass-normalized shapes phi (free unknowns), the
    !! shapes sampled at the stations (raw: as phi is scaled), and their
    !! derivatives with respect to the parameters wrt (1-based indices).
    !! wrt and the station arrays hold at least one entry each (f2py passes
    !! no empty arrays): nwrt and nsta say how many are used. spin = (Omega
    !! rad/s, coriolis 0/1): the modes about a steady hub spin (0: none).
    !! wire_length > 0: the modes about a radial wire's equilibrium (the load
    !! zero), tension its tension at q (N) and dtension dT/dp.
    subroutine api_modal(nbeams, nparams, params, nepb, load, spin, wire_length, nmodes, nwrt, &
                         mwrt, wrt, nsta, msta, sta_kind, sta_beam, sta_s, nfree, freq, zeta, &
                         damped, q, phi, dq, dfreq, dzeta, dphi, shapes, dshapes, tension, &
                         dtension, code, message)
        !f2py intent(hide) nparams, mwrt, msta
        integer(c_int), intent(in) :: nbeams, nparams, nepb, nmodes, nwrt, mwrt, nsta, msta
        integer(c_int), intent(in) :: nfree
        real(c_double), intent(in) :: params(nparams), load(4), spin(2), sta_s(msta)
        real(c_double), intent(in) :: wire_length
        integer(c_int), intent(in) :: wrt(mwrt), sta_kind(msta), sta_beam(msta)
        real(c_double), intent(out) :: freq(nmodes), zeta(nmodes), q(nfree), &
                                       phi(nfree, nmodes), dq(nfree, nwrt), &
                                       dfreq(nmodes, nwrt), dzeta(nmodes, nwrt), &
                                       dphi(nfree, nmodes, nwrt), shapes(nsta, nmodes), &
                                       dshapes(nsta, nmodes, nwrt), tension, dtension(nwrt)
        integer(c_int), intent(out) :: damped, code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(modal_spec_t) :: spec
        type(modal_out_t) :: out
        type(status_t) :: stat
        integer :: i, j, k
        damped = 0
        tension = 0.0_c_double
        if (nwrt < 0 .or. nwrt > mwrt .or. nsta < 0 .or. nsta > msta) then
            call set_status(stat, ERR_INPUT, 'api_modal', 'nwrt = '//fmt_int(nwrt)// &
                            ', nsta = '//fmt_int(nsta)//': more than the arrays hold')
            call status_out(stat, code, message)
            return
        end if
        call fe_mesh_from_params(nbeams, params, nepb, mesh, stat)
        if (stat%code == STATUS_OK) call fe_load_from_values(load, spec%load, stat)
        if (stat%code == STATUS_OK .and. mesh%nfree /= nfree) &
            call set_status(stat, ERR_INPUT, 'api_modal', 'nfree = '//fmt_int(nfree)// &
                            ', expected '//fmt_int(mesh%nfree))
        if (stat%code == STATUS_OK) then
            spec%elements_per_beam = nepb
            spec%spin_rate = spin(1)
            spec%coriolis = spin(2) /= 0.0_c_double
            spec%wire_length = wire_length
            call modal_solve(nbeams, params, spec, nmodes, wrt(1:nwrt), out, stat)
        end if
        if (stat%code == STATUS_OK) call modal_check_stations(mesh, sta_kind(1:nsta), sta_beam(1:nsta), &
                                                                     sta_s(1:nsta), stat)
        if (stat%code == STATUS_OK) then
            freq = out%freq
            zeta = out%zeta
            damped = merge(1, 0, out%damped)
            tension = out%tension
            dtension = out%dtension
            q = out%q
            phi = out%phi
            dq = out%dq
            dfreq = out%dfreq
            dzeta = out%dzeta
            dphi = out%dphi
            do i = 1, nmodes
                do k = 1, nsta
                    shapes(k, i) = modal_station(mesh, out%q, out%phi(:, i), sta_kind(k), &
                                                 sta_beam(k), sta_s(k), &
                                                 out%thickness(sta_beam(k)))
                    do j = 1, nwrt
                        dshapes(k, i, j) = modal_station_sens(mesh, out, i, j, sta_kind(k), &
                                                              sta_beam(k), sta_s(k))
                    end do
                end do
            end do
        end if
        call status_out(stat, code, message)
    end subroutine api_modal

end module beamid_api_modal
