!> Sensitivities of the arc-length static solver (Eq. 44-51, the implicit
!! function theorem on the shooting residual; beamid_arclength solve_static)
!! against central differences of the outputs, for a tip force with a tip
!! moment and for the radial wire, with every effect that enters the
!! variational equations switched on (cubic moment law, elbow and root
!! hinges, partial axial coupling).
program test_static_sensitivities
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK
    use beamid_model, only: chain_t, chain_from_vector, param_count, param_name
    use beamid_presets, only: preset_params
    use beamid_arclength, only: static_load_t, static_options_t, static_solution_t, &
                                solve_static, LOAD_TIP, LOAD_WIRE, NOUT
    use beamid_testing, only: checks_t, check_true, check_finish
    implicit none

    character(len=*), parameter :: wrt_names(9) = [character(len=14) :: 'L1', 'EI1', 'C1', &
        'L2', 'EI2', 'C2', 'elbow_flex', 'root_flex', 'axial_coupling']
    type(checks_t) :: t
    type(static_load_t) :: load
    real(dp), allocatable :: base(:)
    integer :: nb

    call base_model(nb, base)
    load%kind = LOAD_TIP
    load%fx = -2.0_dp
    load%fy = 7.0_dp
    load%moment = 1.0_dp
    call sensitivities_match_central_differences(nb, base, load, 'tip force and moment')
    load = static_load_t()
    load%kind = LOAD_WIRE
    load%wire_length = 1.2_dp
    call sensitivities_match_central_differences(nb, base, load, 'radial wire')
    call check_finish(t, 'test_static_sensitivities')

contains

    !> PACE with C1 = 3, C2 = 7, elbow_flex = 0.01, root_flex = 0.02 and
    !! axial_coupling = 0.5.
    subroutine base_model(nb, params)
        integer, intent(out) :: nb
        real(dp), allocatable, intent(out) :: params(:)
        type(status_t) :: stat
        call preset_params('pace', nb, params, stat)
        call check_true(t, 'pace preset', stat%code == STATUS_OK)
        params(index_of(nb, 'C1')) = 3.0_dp
        params(index_of(nb, 'C2')) = 7.0_dp
        params(index_of(nb, 'elbow_flex')) = 0.01_dp
        params(index_of(nb, 'root_flex')) = 0.02_dp
        params(index_of(nb, 'axial_coupling')) = 0.5_dp
    end subroutine base_model

    integer function index_of(nb, name)
        integer, intent(in) :: nb
        character(len=*), intent(in) :: name
        integer :: i
        index_of = 0
        do i = 1, param_count(nb)
            if (param_name(nb, i) == name) index_of = i
        end do
        call check_true(t, 'parameter '//name//' exists', index_of > 0)
    end function index_of

    subroutine solve(nb, params, load, wrt, sol)
        integer, intent(in) :: nb, wrt(:)
        real(dp), intent(in) :: params(:)
        type(static_load_t), intent(in) :: load
        type(static_solution_t), intent(out) :: sol
        type(chain_t) :: chain
        type(static_options_t) :: opts
        type(status_t) :: stat
        opts%tol = 1.0e-12_dp
        call chain_from_vector(nb, params, chain, stat)
        if (stat%code == STATUS_OK) call solve_static(chain, load, wrt, opts, sol, stat)
        call check_true(t, 'static solve: '//trim(stat%message), stat%code == STATUS_OK)
    end subroutine solve

    !> d output / d parameter against (plus - minus) / 2h with h = 1e-5 of
    !! the parameter (at least 1e-7); the scale of an output is its magnitude
    !! per unit relative change of the parameter.
    subroutine sensitivities_match_central_differences(nb, base, load, label)
        integer, intent(in) :: nb
        real(dp), intent(in) :: base(:)
        type(static_load_t), intent(in) :: load
        character(len=*), intent(in) :: label
        type(static_solution_t) :: sol, plus, minus
        real(dp) :: p(size(base)), h, fd, scale, err
        integer :: wrt(size(wrt_names)), j, k, i
        character(len=160) :: what
        do j = 1, size(wrt_names)
            wrt(j) = index_of(nb, trim(wrt_names(j)))
        end do
        call solve(nb, base, load, wrt, sol)
        do j = 1, size(wrt)
            i = wrt(j)
            h = 1.0e-5_dp*max(abs(base(i)), 0.01_dp)
            p = base
            p(i) = base(i) + h
            call solve(nb, p, load, [integer ::], plus)
            p(i) = base(i) - h
            call solve(nb, p, load, [integer ::], minus)
            do k = 1, NOUT
                if (plus%outputs(k) /= plus%outputs(k)) cycle   ! NaN: no wire force
                fd = (plus%outputs(k) - minus%outputs(k))/(2.0_dp*h)
                scale = max(abs(fd), 1.0e-3_dp*max(abs(plus%outputs(k)), 1.0e-3_dp) &
                            /max(abs(base(i)), 0.01_dp))
                err = abs(sol%doutputs(k, j) - fd)
                write (what, '(a, i0, a, es12.4, a, es12.4)') label//': d output ', k, &
                    ' / d '//trim(wrt_names(j))//' = ', sol%doutputs(k, j), ', differences ', fd
                call check_true(t, trim(what), err <= 1.0e-6_dp*scale + 1.0e-9_dp)
            end do
        end do
    end subroutine sensitivities_match_central_differences
end program test_static_sensitivities
