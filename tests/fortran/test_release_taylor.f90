!> Taylor test of the release sensitivities (beamid_release
!! release_response: the released shape by the implicit function theorem
!! and the forward sensitivities of Eq. 135-140 carried by the integrator).
!! In a random direction dp of several parameters and the release load,
!!   e0(h) = |y(p + h dp) - y(p)|           falls like h   (order 1),
!!   e1(h) = |y(p + h dp) - y(p) - h S dp|  falls like h^2 (order 2),
!! S the sensitivity matrix, y every exported quantity at every output time
!! (each relative to its range over the run), h = 1e-2 .. 1e-4 relative;
!! the observed order between successive h within 0.1 of 1 and of 2.
!! A wrong column would leave e1 of order h. Implicit integrator at rtol
!! 1e-11 (the integration error stays far below e1 at h = 1e-4), 2 elements
!! per beam, spans of 0.05-0.1 s; one case smooth (drag, Kelvin-Voigt),
!! one with Coulomb friction whose sign switches (the jump conditions), one
!! with the tip motor and its lag.
program test_release_taylor
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK
    use beamid_model, only: chain_t, chain_from_vector, param_count, param_name
    use beamid_presets, only: preset_params
    use beamid_fe_assembly, only: fe_load_t
    use beamid_release, only: release_spec_t, release_out_t, release_response, &
                              release_load_index, LOAD_FY, LOAD_MOMENT, NQTY
    use beamid_integrators, only: METHOD_IMPLICIT
    use beamid_testing, only: checks_t, check_true, check_close, check_finish, seed_random
    implicit none

    real(dp), parameter :: hs(3) = [1.0e-2_dp, 1.0e-3_dp, 1.0e-4_dp]
    type(checks_t) :: t

    call seed_random(25)
    call taylor('smooth (drag, Kelvin-Voigt)', &
                [character(len=14) :: 'EI1', 'EA1', 'rho1', 'EI2', 'm_tip', 'c_elbow', &
                 'c_tip', 'eta', 'J_elbow'], &
                [character(len=14) :: 'c_elbow', 'c_tip', 'eta'], [0.5_dp, 0.3_dp, 0.01_dp], &
                0.0_dp, 0.1_dp)
    call taylor('Coulomb friction', &
                [character(len=14) :: 'EI1', 'rho2', 'm_elbow', 'mu_elbow', 'mu_tip'], &
                [character(len=14) :: 'mu_elbow', 'mu_tip', 'J_elbow', 'J_tip'], &
                [0.01_dp, 0.02_dp, 0.0_dp, 0.0_dp], 0.0_dp, 0.1_dp, min_events=2)
    call taylor('tip motor with lag', &
                [character(len=14) :: 'r_motor', 'tau_motor', 'EI2', 'rho1'], &
                [character(len=14) :: 'tau_motor'], [0.01_dp], 0.2_dp, 0.05_dp)
    call check_finish(t, 'test_release_taylor')

contains

    integer function index_of(nb, name)
        integer, intent(in) :: nb
        character(len=*), intent(in) :: name
        integer :: i
        index_of = 0
        do i = 1, param_count(nb)
            if (param_name(nb, i) == trim(name)) index_of = i
        end do
        call check_true(t, 'parameter '//trim(name)//' exists', index_of > 0)
    end function index_of

    !> One response of PACE with `params` under the tip load `load`.
    subroutine run(nb, params, load, gain, times, wrt, out)
        integer, intent(in) :: nb, wrt(:)
        real(dp), intent(in) :: params(:), gain, times(:)
        type(fe_load_t), intent(in) :: load
        type(release_out_t), intent(out) :: out
        type(chain_t) :: chain
        type(status_t) :: stat
        call chain_from_vector(nb, params, chain, stat)
        if (stat%code == STATUS_OK) call release_response(chain, &
            release_spec_t(elements_per_beam=2, load=load, motor_gain=gain, &
                           integrator=METHOD_IMPLICIT, rtol=1.0e-11_dp), times, wrt, out, stat)
        call check_true(t, 'release_response: '//trim(stat%message), stat%code == STATUS_OK)
    end subroutine run

    !> The Taylor test in a random direction of the parameters `names` and
    !! the load's fy and moment, on PACE with `set` = `values`.
    subroutine taylor(label, names, set, values, gain, span, min_events)
        character(len=*), intent(in) :: label
        character(len=*), intent(in) :: names(:), set(:)
        real(dp), intent(in) :: values(:), gain, span
        integer, intent(in), optional :: min_events
        type(release_out_t) :: base, moved
        type(fe_load_t) :: load, load_h
        real(dp), allocatable :: params(:), p(:), r(:), dp_dir(:), times(:), lin(:, :), &
                                 scale(:), e0(:), e1(:)
        integer, allocatable :: wrt(:)
        integer :: nb, j, k, nw, nt
        type(status_t) :: stat
        character(len=160) :: what
        call preset_params('pace', nb, params, stat)
        do j = 1, size(set)
            params(index_of(nb, set(j))) = values(j)
        end do
        load = fe_load_t(0.0_dp, 8.0_dp, 0.3_dp)
        nw = size(names) + 2
        allocate (wrt(nw))
        do j = 1, size(names)
            wrt(j) = index_of(nb, names(j))
        end do
        wrt(nw - 1) = release_load_index(nb, LOAD_FY)
        wrt(nw) = release_load_index(nb, LOAD_MOMENT)
        ! a random direction, each component a fraction (-1..1) of its value
        allocate (r(nw))
        call random_number(r)
        r = 2.0_dp*r - 1.0_dp
        dp_dir = r*[params(wrt(1:nw - 2)), load%fy, load%moment]
        nt = 6
        times = [(span*k/(nt - 1), k=0, nt - 1)]
        call run(nb, params, load, gain, times, wrt, base)
        if (t%failed > 0) return
        ! with friction: the sign switches within the span (the jump
        ! conditions are exercised, not avoided)
        if (present(min_events)) call check_true(t, label//': friction switches', &
                                                 base%hist%nevents >= min_events)
        ! S dp for every quantity and time
        allocate (lin(NQTY, nt), scale(NQTY), e0(size(hs)), e1(size(hs)))
        lin = 0.0_dp
        do j = 1, nw
            lin = lin + base%dy(:, :, j)*dp_dir(j)
        end do
        do k = 1, NQTY
            scale(k) = max(maxval(base%y(k, :)) - minval(base%y(k, :)), &
                           1.0e-3_dp*maxval(abs(base%y(k, :))), 1.0e-12_dp)
        end do
        do k = 1, size(hs)
            p = params
            p(wrt(1:nw - 2)) = params(wrt(1:nw - 2)) + hs(k)*dp_dir(1:nw - 2)
            load_h = fe_load_t(load%fx, load%fy + hs(k)*dp_dir(nw - 1), &
                               load%moment + hs(k)*dp_dir(nw))
            call run(nb, p, load_h, gain, times, [integer ::], moved)
            if (t%failed > 0) return
            e0(k) = maxval(abs(moved%y - base%y)/spread(scale, 2, nt))
            e1(k) = maxval(abs(moved%y - base%y - hs(k)*lin)/spread(scale, 2, nt))
        end do
        do k = 1, size(hs) - 1
            write (what, '(a, es8.1, a, es8.1, a, f6.3, a, f6.3)') label//': h ', hs(k), &
                ' -> ', hs(k + 1), ': order of e0 ', log(e0(k)/e0(k + 1))/log(hs(k)/hs(k + 1)), &
                ', of e1 ', log(e1(k)/e1(k + 1))/log(hs(k)/hs(k + 1))
            write (*, '(a)') trim(what)
            call check_close(t, trim(what)//' (e0 order 1)', &
                             log(e0(k)/e0(k + 1))/log(hs(k)/hs(k + 1)), 1.0_dp, 0.0_dp, 0.1_dp)
            call check_close(t, trim(what)//' (e1 order 2)', &
                             log(e1(k)/e1(k + 1))/log(hs(k)/hs(k + 1)), 2.0_dp, 0.0_dp, 0.1_dp)
        end do
    end subroutine taylor
end program test_release_taylor
