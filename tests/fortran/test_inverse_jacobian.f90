!> The inverse problem's Jacobian assembly (beamid_inverse: inverse_evaluate
!! scatters each experiment family's rows back in data order) against
!! central differences of its own predictions, on a small problem: PACE with
!! the cubic law, elbow and root hinges and partial axial coupling, a tip load, a
!! wire and a short release (2 elements per beam, rtol 1e-11), their rows
!! interleaved (every static quantity, u_tip with its -1 per length, the
!! release's static shape at t = 0 and two later times), the columns asked in
!! a shuffled order with parameters one family ignores (rho1, m_tip: zero
!! in the static rows). Also: the predictions do not depend on the columns
!! asked, and a column asked twice comes back twice.
program test_inverse_jacobian
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK
    use beamid_model, only: param_count, param_name
    use beamid_presets, only: preset_params
    use beamid_inverse, only: inverse_problem_t, inverse_problem_init, EXP_TIP, EXP_WIRE, &
                              EXP_RELEASE, EV_FX, EV_FY, EV_MOMENT, EV_WIRE_LENGTH, &
                              EV_NEPB, EV_METHOD, EV_LAW, EV_RTOL, experiment_spec_t
    ! rows name observation kinds (no observation list: row_q is the kind)
    use beamid_observations, only: Q_X_TIP => K_X_TIP, Q_Y_TIP => K_Y_TIP, &
                                   Q_TIP_ANGLE => K_TIP_ANGLE, Q_WIRE_FORCE => K_WIRE_FORCE, &
                                   Q_X_ELBOW => K_X_ELBOW, Q_Y_ELBOW => K_Y_ELBOW, &
                                   Q_U_TIP => K_U_TIP, Q_W_TIP => K_W_TIP
    use beamid_integrators, only: METHOD_IMPLICIT
    use beamid_dynamics, only: FRICTION_SIGN
    use beamid_family, only: SPEC_KEYS, spec_key_index
    use beamid_testing, only: checks_t, check_true, check_close, check_finish
    implicit none

    type(checks_t) :: t
    real(dp), allocatable :: base(:)
    type(experiment_spec_t), allocatable :: specs(:)
    integer, allocatable :: exp_kind(:)
    integer :: nb, k
    type(status_t) :: stat

    call preset_params('pace', nb, base, stat)
    call check_true(t, 'pace preset', stat%code == STATUS_OK)
    base(index_of('C1')) = 3.0_dp
    base(index_of('C2')) = 7.0_dp
    base(index_of('elbow_flex')) = 0.01_dp
    base(index_of('axial_coupling')) = 0.5_dp
    base(index_of('root_flex')) = 0.005_dp

    ! experiments: 1 tip load, 2 release, 3 wire
    exp_kind = [EXP_TIP, EXP_RELEASE, EXP_WIRE]
    allocate (specs(3))
    call specs(1)%set(EV_FX, -2.0_dp)
    call specs(1)%set(EV_FY, 7.0_dp)
    call specs(1)%set(EV_MOMENT, 1.0_dp)
    call specs(2)%set(EV_FY, 8.0_dp)
    call specs(2)%set(EV_NEPB, 2.0_dp)
    call specs(2)%set(EV_METHOD, real(METHOD_IMPLICIT, dp))
    call specs(2)%set(EV_LAW, real(FRICTION_SIGN, dp))
    ! by name, as the deck and the binding name them
    call specs(2)%set_named('rtol', 1.0e-11_dp, stat)
    call specs(3)%set_named('wire_length', 1.2_dp, stat)
    call check_true(t, 'spec keys set by name', stat%code == STATUS_OK)
    call check_close(t, 'spec: rtol by key', specs(2)%get(EV_RTOL), 1.0e-11_dp, 0.0_dp, 0.0_dp)
    call check_close(t, 'spec: wire_length by name', specs(3)%value_of('wire_length'), &
                     1.2_dp, 0.0_dp, 0.0_dp)
    call check_true(t, 'spec: wire_length is a key', &
                    spec_key_index('wire_length') == EV_WIRE_LENGTH)
    call check_close(t, 'spec: a key not set is 0', specs(3)%get(EV_NEPB), 0.0_dp, 0.0_dp, 0.0_dp)
    call specs(1)%set_named('no_such_key', 1.0_dp, stat)
    call check_true(t, 'spec: an unknown name is an input error naming it', &
                    stat%code /= STATUS_OK .and. index(stat%message, 'no_such_key') > 0)
    stat = status_t()
    ! each key's identifier is its index in the one key table
    do k = 1, size(SPEC_KEYS)
        call check_true(t, 'spec key '//trim(SPEC_KEYS(k)%name)//' identifier', &
                        SPEC_KEYS(k)%key == k)
    end do

    ! the static experiments alone, with the lengths (which the release's
    ! mesh depends on: no release sensitivity with respect to them)
    call check_assembly('static', [1, 3, 1, 3, 1, 3, 1, 1, 3, 1], &
                        [Q_X_TIP, Q_WIRE_FORCE, Q_TIP_ANGLE, Q_Y_TIP, Q_U_TIP, Q_Y_ELBOW, &
                         Q_Y_ELBOW, Q_X_ELBOW, Q_U_TIP, Q_W_TIP], spread(0.0_dp, 1, 10), &
                        [character(len=14) :: 'EI2', 'L1', 'C1', 'elbow_flex', 'L2', &
                         'axial_coupling', 'EA1', 'root_flex'])
    ! all three, interleaved
    call check_assembly('mixed', [1, 3, 2, 1, 2, 3, 1, 2, 3, 1, 2, 1, 3, 2], &
                        [Q_X_TIP, Q_WIRE_FORCE, Q_W_TIP, Q_TIP_ANGLE, Q_X_ELBOW, Q_Y_TIP, &
                         Q_U_TIP, Q_TIP_ANGLE, Q_Y_ELBOW, Q_Y_ELBOW, Q_U_TIP, Q_X_ELBOW, &
                         Q_W_TIP, Q_Y_TIP], &
                        [0.0_dp, 0.0_dp, 0.02_dp, 0.0_dp, 0.05_dp, 0.0_dp, 0.0_dp, 0.0_dp, &
                         0.0_dp, 0.0_dp, 0.05_dp, 0.0_dp, 0.0_dp, 0.02_dp], &
                        [character(len=14) :: 'EI2', 'rho1', 'C1', 'elbow_flex', 'm_tip', &
                         'axial_coupling', 'EA1', 'root_flex'])
    call check_finish(t, 'test_inverse_jacobian')

contains

    integer function index_of(name)
        character(len=*), intent(in) :: name
        integer :: i
        index_of = 0
        do i = 1, param_count(nb)
            if (param_name(nb, i) == name) index_of = i
        end do
        call check_true(t, 'parameter '//name//' exists', index_of > 0)
    end function index_of

    !> Each column of the problem of experiments 1-3 with rows (row_exp,
    !! row_q, row_t), columns `names`, against (plus - minus) / 2h, h = 1e-5
    !! of the parameter (at least 1e-7), row by row; the scale of a row is its
    !! central difference or 1e-3 of its value per unit relative change of
    !! the parameter. Static rows to 1e-6 of that (the arc-length solver at
    !! tol 1e-12), release rows to 1e-4 (integrated at rtol 1e-11).
    subroutine check_assembly(label, row_exp, row_q, row_t, names)
        character(len=*), intent(in) :: label
        integer, intent(in) :: row_exp(:), row_q(:)
        real(dp), intent(in) :: row_t(:)
        character(len=*), intent(in) :: names(:)
        type(inverse_problem_t) :: prob
        type(status_t) :: st
        integer :: m, i, j, k
        integer, allocatable :: wrt(:), static_rows(:), release_rows(:)
        real(dp), allocatable :: pred(:), jac(:, :), pred0(:), jac0(:, :), plus(:), minus(:), &
                                 jac2(:, :), p(:)
        real(dp) :: h, fd, scale, tol
        character(len=200) :: what
        call inverse_problem_init(nb, exp_kind, specs, row_exp, row_t, row_q, 1.0e-12_dp, &
                                  prob, st)
        call check_true(t, label//': inverse_problem_init: '//trim(st%message), &
                        st%code == STATUS_OK)
        if (st%code /= STATUS_OK) return
        wrt = [(index_of(trim(names(j))), j=1, size(names))]
        m = size(row_exp)
        static_rows = pack([(i, i=1, m)], row_exp /= 2)
        release_rows = pack([(i, i=1, m)], row_exp == 2 .and. row_t > 0.0_dp)
        allocate (pred(m), pred0(m), plus(m), minus(m), jac(m, size(wrt)), jac0(m, 0), &
                  jac2(m, 2))
        call evaluate(prob, label, base, wrt, pred, jac)
        call evaluate(prob, label, base, [integer ::], pred0, jac0)
        call check_close(t, label//': predictions do not depend on the columns asked', pred, &
                         pred0, 0.0_dp, 0.0_dp)
        call evaluate(prob, label, base, [wrt(3), wrt(3)], pred0, jac2)
        call check_close(t, label//': a column asked twice', jac2(:, 2), jac(:, 3), 0.0_dp, &
                         0.0_dp)
        call check_close(t, label//': ... is the column asked once', jac2(:, 1), jac(:, 3), &
                         0.0_dp, 0.0_dp)
        do j = 1, size(wrt)
            k = wrt(j)
            h = 1.0e-5_dp*max(abs(base(k)), 0.01_dp)
            p = base
            p(k) = base(k) + h
            call evaluate(prob, label, p, [integer ::], plus, jac0)
            p(k) = base(k) - h
            call evaluate(prob, label, p, [integer ::], minus, jac0)
            do i = 1, m
                fd = (plus(i) - minus(i))/(2.0_dp*h)
                scale = max(abs(fd), 1.0e-3_dp*max(abs(pred(i)), 1.0e-3_dp) &
                            /max(abs(base(k)), 0.01_dp))
                tol = merge(1.0e-4_dp, 1.0e-6_dp, row_exp(i) == 2)
                write (what, '(a, i0, a, es12.4, a, es12.4)') label//': row ', i, ': d / d '// &
                    trim(names(j))//' = ', jac(i, j), ', central differences ', fd
                call check_true(t, trim(what), abs(jac(i, j) - fd) <= tol*scale + 1.0e-9_dp)
            end do
            ! parameters the statics ignore: exact zeros in every static row
            if (trim(names(j)) == 'rho1' .or. trim(names(j)) == 'm_tip') then
                call check_true(t, label//': '//trim(names(j))//' zero in the static rows', &
                                all(jac(static_rows, j) == 0.0_dp))
                call check_true(t, label//': '//trim(names(j))//' nonzero in the release rows', &
                                any(jac(release_rows, j) /= 0.0_dp))
            end if
        end do
    end subroutine check_assembly

    subroutine evaluate(prob, label, params, cols, pred, jac)
        type(inverse_problem_t), intent(inout) :: prob
        character(len=*), intent(in) :: label
        real(dp), intent(in) :: params(:)
        integer, intent(in) :: cols(:)
        real(dp), intent(out) :: pred(:), jac(:, :)
        type(status_t) :: st
        call prob%evaluate(params, cols, pred, jac, st)
        call check_true(t, label//': evaluate: '//trim(st%message), st%code == STATUS_OK)
    end subroutine evaluate
end program test_inverse_jacobian
