!> The modal analysis about a static equilibrium (beamid_modal, issue 27):
!! frequency, damping-ratio, mode-shape (Nelson) and station-shape
!! derivatives against (five-point) central differences of the whole analysis (static
!! solve and eigenproblem redone at p +- h), with every effect that changes
!! stiffness, mass or damping switched on: the cubic law, elbow and root
!! hinges, rotary inertia, a tip force and an exact tip moment, and, in the
!! damped case, drag and Kelvin-Voigt damping.
program test_modal
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK
    use beamid_model, only: param_count, param_name
    use beamid_presets, only: preset_params
    use beamid_fe_assembly, only: fe_mesh_t, fe_mesh_build, FE_MOMENT_EXACT, fe_load_t, &
                                  fe_residual, fe_band_rows, fe_band_to_dense, fe_wire_force, &
                                  fe_wire_jacobian, fe_wire_tip
    use beamid_fe_static, only: fe_solve_wire, fe_newton_opts_t, fe_solve_info_t
    use beamid_model, only: chain_t, chain_from_vector
    use beamid_modal, only: modal_spec_t, modal_out_t, modal_solve, modal_station, &
                            modal_station_sens, SHAPE_N, SHAPE_T, SHAPE_PSI, SHAPE_STRAIN
    use beamid_modal, only: modal_system, modal_matrices, modal_matrices_dir, modal_station_dq
    use beamid_dynamics, only: dyn_system_t
    use beamid_fe_element, only: fe_element_tangent, fe_element_tangent_dir, fe_gauss_points, &
                                 fe_hinge_tangent, fe_hinge_tangent_dir
    use beamid_testing, only: checks_t, check_true, check_finish, check_close, check_below
    implicit none

    ! thick2: the gauge strain's kappa/2 at the station (on beam 2); thick1:
    ! zero there
    character(len=*), parameter :: wrt_names(12) = [character(len=12) :: 'EI1', 'EA2', &
        'rho1', 'C2', 'm_tip', 'J_elbow', 'elbow_flex', 'root_flex', 'c_tip', 'eta', &
        'thick2', 'thick1']
    integer, parameter :: NMODES = 5
    type(checks_t) :: t
    real(dp), allocatable :: base(:)
    type(modal_spec_t) :: spec
    integer :: nb

    call base_model(nb, base)
    spec%elements_per_beam = 3
    spec%load%fx = -2.0_dp
    spec%load%fy = 5.0_dp
    spec%load%moment = 1.0_dp
    spec%load%moment_form = FE_MOMENT_EXACT
    call derivatives_match(nb, base, spec, 'undamped', .false.)
    base(index_of(nb, 'c_tip')) = 0.5_dp
    base(index_of(nb, 'eta')) = 2.0e-3_dp
    call derivatives_match(nb, base, spec, 'damped', .true.)
    call wire_tangent_matches_differences(nb, base)
    call element_tangent_dir_matches_differences()
    call matrices_dir_match_differences(nb, base, spec)
    call check_finish(t, 'test_modal')

contains

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
        params(index_of(nb, 'J_elbow')) = 0.0123_dp
        params(index_of(nb, 'J_tip')) = 0.0015_dp
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

    subroutine solve(nb, params, spec, wrt, out)
        integer, intent(in) :: nb, wrt(:)
        real(dp), intent(in) :: params(:)
        type(modal_spec_t), intent(in) :: spec
        type(modal_out_t), intent(out) :: out
        type(status_t) :: stat
        call modal_solve(nb, params, spec, NMODES, wrt, out, stat)
        call check_true(t, 'modal solve: '//trim(stat%message), stat%code == STATUS_OK)
    end subroutine solve

    subroutine derivatives_match(nb, base, spec, label, damped)
        integer, intent(in) :: nb
        real(dp), intent(in) :: base(:)
        type(modal_spec_t), intent(in) :: spec
        character(len=*), intent(in) :: label
        logical, intent(in) :: damped
        type(modal_out_t) :: out, runs(4)
        type(fe_mesh_t) :: mesh
        type(chain_t) :: chain
        type(status_t) :: stat
        real(dp) :: p(size(base)), h, fd, scale, got, sgn(4), vals(4)
        real(dp), allocatable :: dphi_fd(:)
        integer :: wrt(size(wrt_names)), j, k, i, st, m, kinds(4)
        integer, parameter :: offsets(4) = [-2, -1, 1, 2]
        character(len=200) :: what
        kinds = [SHAPE_N, SHAPE_T, SHAPE_PSI, SHAPE_STRAIN]
        do j = 1, size(wrt_names)
            wrt(j) = index_of(nb, trim(wrt_names(j)))
        end do
        call solve(nb, base, spec, wrt, out)
        call check_true(t, label//': damped flag', out%damped .eqv. damped)
        call chain_from_vector(nb, base, chain, stat)
        call fe_mesh_build(chain, spec%elements_per_beam, mesh, stat)
        do j = 1, size(wrt)
            i = wrt(j)
            if (base(i) == 0.0_dp) cycle
            ! the five-point stencil at h = 1e-2 of the parameter: the lowest
            ! eigenvalues carry a round-off of about eps lambda_max (the axial
            ! modes), 1e-7 relative, too much for a step of 1e-4
            h = 1.0e-2_dp*abs(base(i))
            do st = 1, 4
                p = base
                p(i) = base(i) + real(offsets(st), dp)*h
                call solve(nb, p, spec, [integer ::], runs(st))
            end do
            do k = 1, NMODES
                fd = stencil([(runs(st)%freq(k), st=1, 4)], h)
                scale = out%freq(k)/abs(base(i))
                write (what, '(a, i0, a, 2es14.6)') label//': d freq ', k, ' / d '// &
                    trim(wrt_names(j))//' vs differences', out%dfreq(k, j), fd
                call check_true(t, trim(what), abs(out%dfreq(k, j) - fd) <= 1.0e-4_dp*scale)
                if (damped) then
                    fd = stencil([(runs(st)%zeta(k), st=1, 4)], h)
                    scale = max(out%zeta(k), 1.0e-6_dp)/abs(base(i))
                    write (what, '(a, i0, a, 2es14.6)') label//': d zeta ', k, ' / d '// &
                        trim(wrt_names(j))//' vs differences', out%dzeta(k, j), fd
                    call check_true(t, trim(what), abs(out%dzeta(k, j) - fd) <= 1.0e-4_dp*scale)
                end if
                ! Nelson: the mass-normalized shape, signs aligned with the base
                do st = 1, 4
                    sgn(st) = sign(1.0_dp, dot_product(runs(st)%phi(:, k), out%phi(:, k)))
                end do
                dphi_fd = (sgn(1)*runs(1)%phi(:, k) - 8.0_dp*sgn(2)*runs(2)%phi(:, k) &
                           + 8.0_dp*sgn(3)*runs(3)%phi(:, k) - sgn(4)*runs(4)%phi(:, k)) &
                          /(12.0_dp*h)
                scale = maxval(abs(out%phi(:, k)))/abs(base(i))
                write (what, '(a, i0, a, es12.4)') label//': d phi ', k, ' / d '// &
                    trim(wrt_names(j))//' (Nelson), worst error ', &
                    maxval(abs(out%dphi(:, k, j) - dphi_fd))/scale
                call check_true(t, trim(what), &
                                maxval(abs(out%dphi(:, k, j) - dphi_fd)) <= 1.0e-4_dp*scale)
                do m = 1, 4
                    do st = 1, 4
                        vals(st) = sgn(st)*modal_station(mesh, runs(st)%q, runs(st)%phi(:, k), &
                                                         kinds(m), 2, 0.5_dp, &
                                                         runs(st)%thickness(2))
                    end do
                    fd = stencil(vals, h)
                    got = modal_station_sens(mesh, out, k, j, kinds(m), 2, 0.5_dp)
                    scale = max(abs(modal_station(mesh, out%q, out%phi(:, k), kinds(m), 2, &
                                                  0.5_dp, out%thickness(2))), &
                                abs(fd)*abs(base(i)), 1.0e-12_dp) &
                            /abs(base(i))
                    write (what, '(a, i0, a, i0, a, 2es14.6)') label//': station kind ', &
                        kinds(m), ' mode ', k, ' d/d '//trim(wrt_names(j)), got, fd
                    call check_true(t, trim(what), abs(got - fd) <= 1.0e-4_dp*scale)
                end do
            end do
        end do
    end subroutine derivatives_match

    !> f'(x) from f(x - 2h), f(x - h), f(x + h), f(x + 2h) (error O(h^4)).
    pure real(dp) function stencil(f, h)
        real(dp), intent(in) :: f(4), h
        stencil = (f(1) - 8.0_dp*f(2) + 8.0_dp*f(3) - f(4))/(12.0_dp*h)
    end function stencil
    !> The radial wire in the FE model (fe_solve_wire): the equilibrium lies
    !! on the wire's circle with zero residual NLT + T e, and the tangent
    !! with the wire's geometric stiffness, d(NLT - Q_wire)/dq at fixed T,
    !! matches central differences of the residual, at q* and off it.
    subroutine wire_tangent_matches_differences(nb, params)
        integer, intent(in) :: nb
        real(dp), intent(in) :: params(:)
        type(chain_t) :: chain
        type(fe_mesh_t) :: mesh
        type(status_t) :: stat
        type(fe_newton_opts_t) :: opts
        type(fe_solve_info_t) :: info
        real(dp), allocatable :: q(:), r(:), rp(:), rm(:), jb(:, :), k(:, :), kd(:, :), qt(:)
        real(dp) :: tension, x(2), rad, h
        integer :: n, i, iu, iw, pass
        call chain_from_vector(nb, params, chain, stat)
        call fe_mesh_build(chain, 3, mesh, stat)
        call check_true(t, 'wire: mesh', stat%code == STATUS_OK)
        n = mesh%nfree
        allocate (q(n), r(n), rp(n), rm(n), qt(n), jb(fe_band_rows(mesh), n), k(n, n), kd(n, n))
        call fe_solve_wire(mesh, 1.3_dp, q, tension, opts, info, stat)
        call check_true(t, 'wire: equilibrium found', stat%code == STATUS_OK .and. &
                        tension > 0.0_dp)
        call fe_wire_tip(mesh, q, iu, iw, x, rad)
        call check_close(t, 'wire: tip on the circle', rad, 1.3_dp, 0.0_dp, 1.0e-12_dp)
        call wire_res(mesh, tension, q, r)
        call check_below(t, 'wire: residual at q*', maxval(abs(r)), 1.0e-8_dp*tension)
        do pass = 1, 2
            qt = q
            if (pass == 2) qt = q + 0.01_dp*[(sin(real(i, dp)), i=1, n)]
            call fe_residual(mesh, fe_load_t(), qt, r, jb)
            call fe_wire_jacobian(mesh, qt, tension, -1.0_dp, jb)
            call fe_band_to_dense(jb, mesh%kl, mesh%ku, k)
            h = 1.0e-6_dp
            do i = 1, n
                qt(i) = qt(i) + h
                call wire_res(mesh, tension, qt, rp)
                qt(i) = qt(i) - 2.0_dp*h
                call wire_res(mesh, tension, qt, rm)
                qt(i) = qt(i) + h
                kd(:, i) = (rp - rm)/(2.0_dp*h)
            end do
            call check_close(t, 'wire: tangent vs central differences', k, kd, 1.0e-6_dp, &
                             1.0e-6_dp*maxval(abs(k)))
        end do
    end subroutine wire_tangent_matches_differences

    !> NLT(q) - Q_wire(q) at the fixed tension.
    subroutine wire_res(mesh, tension, qq, rr)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: tension, qq(:)
        real(dp), intent(out) :: rr(:)
        real(dp), allocatable :: qv(:)
        allocate (qv(size(qq)))
        call fe_residual(mesh, fe_load_t(), qq, rr)
        call fe_wire_force(mesh, qq, tension, qv)
        rr = rr - qv
    end subroutine wire_res

    !> Pseudo-random entries in (-amp, amp) from a fixed sequence.
    function pattern(n, seed, amp) result(x)
        integer, intent(in) :: n, seed
        real(dp), intent(in) :: amp
        real(dp) :: x(n)
        integer :: i
        do i = 1, n
            x(i) = amp*sin(12.9898_dp*real(i + 7*seed, dp) + 78.233_dp*real(seed, dp))
        end do
    end function pattern

    !> The hand-coded directional derivatives of the element tangent and of
    !! the hinge tangent against central differences of the tangent along
    !! pseudo-random directions at a deformed state.
    subroutine element_tangent_dir_matches_differences()
        real(dp) :: xg(7), wg(7), qe(8), ve(8), f(8), kp(8, 8), km(8, 8), dk(8, 8), s(4), &
                    vs(4), f4(4), kp4(4, 4), km4(4, 4), dk4(4, 4), h
        integer :: dir
        character(len=1) :: tag
        call fe_gauss_points(7, xg, wg)
        h = 1.0e-6_dp
        do dir = 1, 3
            write (tag, '(i1)') dir
            qe = pattern(8, dir, 0.2_dp)
            ve = pattern(8, dir + 10, 1.0_dp)
            call fe_element_tangent_dir(0.3_dp, 50.0_dp, 2.0_dp, 5.0_dp, xg, wg, qe, ve, dk)
            call fe_element_tangent(0.3_dp, 50.0_dp, 2.0_dp, 5.0_dp, xg, wg, qe + h*ve, f, kp)
            call fe_element_tangent(0.3_dp, 50.0_dp, 2.0_dp, 5.0_dp, xg, wg, qe - h*ve, f, km)
            call check_true(t, 'element tangent dir '//tag//': nonzero', maxval(abs(dk)) > 1.0_dp)
            call check_below(t, 'element tangent dir '//tag//' vs central differences', &
                             maxval(abs(dk - (kp - km)/(2.0_dp*h))), 1.0e-6_dp*maxval(abs(dk)))
            s = pattern(4, dir + 20, 0.3_dp)
            vs = pattern(4, dir + 30, 1.0_dp)
            call fe_hinge_tangent_dir(0.01_dp, s, vs, dk4)
            call fe_hinge_tangent(0.01_dp, s + h*vs, f4, kp4)
            call fe_hinge_tangent(0.01_dp, s - h*vs, f4, km4)
            call check_true(t, 'hinge tangent dir '//tag//': nonzero', maxval(abs(dk4)) > 1.0_dp)
            call check_below(t, 'hinge tangent dir '//tag//' vs central differences', &
                             maxval(abs(dk4 - (kp4 - km4)/(2.0_dp*h))), 1.0e-6_dp*maxval(abs(dk4)))
        end do
    end subroutine element_tangent_dir_matches_differences

    !> modal_matrices_dir (K_T with the hinges, the cubic law and the exact
    !! tip moment or a wire's tension; M with rotary inertia; C with
    !! Kelvin-Voigt damping and drag) against central differences of
    !! modal_matrices along pseudo-random directions at a deformed state.
    subroutine matrices_dir_match_differences(nb, base, spec)
        integer, intent(in) :: nb
        real(dp), intent(in) :: base(:)
        type(modal_spec_t), intent(in) :: spec
        type(dyn_system_t) :: sys
        type(status_t) :: stat
        real(dp), allocatable :: params(:), q(:), v(:), nlt(:), kp(:, :), mp(:, :), cp(:, :), &
                                 km(:, :), mm(:, :), cm(:, :), dk(:, :), dm(:, :), dc(:, :)
        real(dp) :: h, tension, got, want
        integer :: n, dir, kind
        character(len=1) :: tag, ktag
        allocate (params, source=base)
        params(index_of(nb, 'c_tip')) = 0.5_dp
        params(index_of(nb, 'eta')) = 2.0e-3_dp
        call modal_system(nb, params, 3, sys, stat)
        call check_true(t, 'matrices dir: system', stat%code == STATUS_OK)
        n = sys%n
        allocate (nlt(n), kp(n, n), mp(n, n), cp(n, n), km(n, n), mm(n, n), cm(n, n), &
                  dk(n, n), dm(n, n), dc(n, n))
        h = 1.0e-6_dp
        do dir = 1, 4
            write (tag, '(i1)') dir
            ! directions 1, 2: the tip moment; 3, 4: a wire's tension
            tension = merge(0.0_dp, 3.0_dp, dir <= 2)
            q = pattern(n, dir + 40, 0.1_dp)
            v = pattern(n, dir + 50, 1.0_dp)
            call modal_matrices_dir(sys, spec%load, q, v, tension, dk, dm, dc)
            call modal_matrices(sys, spec%load, q + h*v, kp, mp, cp, nlt, tension)
            call modal_matrices(sys, spec%load, q - h*v, km, mm, cm, nlt, tension)
            call check_true(t, 'matrices dir '//tag//': dK, dM, dC nonzero', &
                            maxval(abs(dk)) > 0.0_dp .and. maxval(abs(dm)) > 0.0_dp .and. &
                            maxval(abs(dc)) > 0.0_dp)
            call check_below(t, 'matrices dir '//tag//': dK_T vs central differences', &
                             maxval(abs(dk - (kp - km)/(2.0_dp*h))), 1.0e-6_dp*maxval(abs(dk)))
            call check_below(t, 'matrices dir '//tag//': dM vs central differences', &
                             maxval(abs(dm - (mp - mm)/(2.0_dp*h))), 1.0e-6_dp*maxval(abs(dm)))
            call check_below(t, 'matrices dir '//tag//': dC vs central differences', &
                             maxval(abs(dc - (cp - cm)/(2.0_dp*h))), 1.0e-6_dp*maxval(abs(dc)))
            ! a station's sampling frame moving with q (modal_station_dq), every kind
            do kind = 1, 6
                got = modal_station_dq(sys%mesh, q, v, dir_vec(n), kind, 2, 0.37_dp, 3.0e-3_dp)
                want = (modal_station(sys%mesh, q + h*v, dir_vec(n), kind, 2, 0.37_dp, &
                                      3.0e-3_dp) &
                        - modal_station(sys%mesh, q - h*v, dir_vec(n), kind, 2, 0.37_dp, &
                                        3.0e-3_dp))/(2.0_dp*h)
                write (ktag, '(i1)') kind
                call check_close(t, 'station dq '//tag//' kind '//ktag// &
                                 ' vs central differences', got, want, 1.0e-6_dp, 1.0e-9_dp)
                if (kind <= SHAPE_STRAIN) call check_true(t, 'station dq '//tag//' kind '// &
                                                          ktag//': nonzero', abs(got) > 1.0e-3_dp)
            end do
        end do
    end subroutine matrices_dir_match_differences

    function dir_vec(n) result(x)
        integer, intent(in) :: n
        real(dp) :: x(n)
        x = pattern(n, 77, 1.0_dp)
    end function dir_vec

end program test_modal
