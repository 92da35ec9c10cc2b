!> The tasks of a deck (docs/decks.md): run the computation a deck asks for
!! and write its result files, all or none.
!!
!! Tasks: static, fe_static, fe_modes, the estimation tasks fit, compare,
!! diagnose, improve (the same Fortran routines as the Python API, so the same
!! numbers) and simulate (the dynamics of beamid.simulate). beamid-batch and
!! beamid.run (through beamid_api_deck) call run_task, so both fronts write the
!! same bytes.
!!
!! Output files are written only after the computation succeeded, first under
!! temporary names next to their final names ('<name>.tmp'), then renamed
!! together; when any write or rename fails the temporary files are removed
!! and the status (ERR_OUTPUT) names the path. Library code: no printing.
module beamid_tasks
    use, intrinsic :: iso_c_binding, only: c_int, c_double, c_char, c_null_char
    use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_nan
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK, ERR_OUTPUT, set_status, fmt_int, &
                             set_alloc_error
    use beamid_model, only: chain_t, chain_from_vector, param_name, param_index_beam, IB_L
    use beamid_deck, only: deck_t
    use beamid_arclength, only: static_options_t, static_solution_t, solve_static, LOAD_WIRE, &
                                static_shape, NOUT
    use beamid_fe_assembly, only: fe_mesh_t, fe_load_t
    use beamid_fe_static, only: fe_newton_opts_t
    use beamid_fe_nodes, only: fe_mesh_from_params, fe_setup, fe_static_nodes, fe_modes_table
    ! The dynamics and estimation drivers are the f2py entries (beamid.simulate
    ! and beamid.fit call the same), until issue 11.2 moves their logic into
    ! library modules.
    use beamid_api_estimation, only: api_fit, api_diagnose
    use beamid_release, only: release_spec_t, release_out_t, release_response
    use beamid_estimation, only: residual_structure, chi2_sf
    use beamid_static_experiments, only: static_effect_params, quantity_label
    use beamid_measurements, only: fmt_g
    implicit none
    private

    public :: run_task, output_prefix, files_t

    !> The files of one run: final names, newline separated, in write order.
    type :: files_t
        character(len=:), allocatable :: names
    end type files_t

    !> One fit: the outputs of api_fit.
    type :: fit_out_t
        integer(c_int), allocatable :: free(:), flags(:)
        real(c_double), allocatable :: params(:), sigmas(:), cov(:, :), pred(:), norm(:)
        real(c_double) :: stats(8) = 0.0_c_double
    end type fit_out_t

    !> One diagnosis: the outputs of api_diagnose and the candidate blocks.
    type :: diag_out_t
        integer(c_int), allocatable :: start(:), cparams(:), ranking(:)
        real(c_double), allocatable :: cstats(:, :), pstats(:, :), refit_params(:, :)
        real(c_double) :: dstats(6) = 0.0_c_double
    end type diag_out_t

    !> Flag texts of the estimates (beamid.estimation.FLAG_TEXT).
    character(len=*), parameter :: flag_text(0:4) = [character(len=43) :: 'ok', &
        'not determined by these data', 'ran away from its start', &
        'correlation near +-1 with another parameter', 'at a physical bound']
    !> Candidate states (beamid.diagnosis._STATES).
    character(len=*), parameter :: state_text(0:3) = [character(len=19) :: 'tested', &
        'already free', 'already switched on', 'not in this model']

    character(len=*), parameter :: output_names(NOUT) = [character(len=11) :: &
        'x_tip', 'y_tip', 'tip_angle', 'wire_force', 'x_elbow', 'y_elbow', &
        'elbow_angle', 'root_moment']
    !> Suffix of the temporary name of an output file until the run succeeded.
    character(len=*), parameter :: TMP_SUFFIX = '.tmp'

    interface
        !> C's rename(3): atomic within one file system.
        integer(c_int) function c_rename(old, new) bind(c, name='rename')
            import :: c_int, c_char
            character(kind=c_char), intent(in) :: old(*), new(*)
        end function c_rename
        !> C's remove(3).
        integer(c_int) function c_remove(path) bind(c, name='remove')
            import :: c_int, c_char
            character(kind=c_char), intent(in) :: path(*)
        end function c_remove
    end interface

contains

    !> Run the task of a validated deck and write its files, all or none.
    !! `written` lists the files written (newline separated) on success.
    subroutine run_task(deck, written, stat)
        type(deck_t), intent(in) :: deck
        character(len=:), allocatable, intent(out) :: written
        type(status_t), intent(inout) :: stat
        type(files_t) :: fl
        fl%names = ''
        written = ''
        select case (deck%task)
        case ('fe_static')
            call run_fe_static(deck, fl, stat)
        case ('fe_modes')
            call run_fe_modes(deck, fl, stat)
        case ('fit', 'compare', 'diagnose', 'improve')
            call run_estimation(deck, fl, stat)
        case ('simulate')
            call run_simulate(deck, fl, stat)
        case default
            call run_static(deck, fl, stat)
        end select
        if (stat%code /= STATUS_OK .and. allocated(deck%exp_names)) call name_experiment(deck, stat)
        call finish_files(fl, stat)
        if (stat%code == STATUS_OK) written = fl%names
    end subroutine run_task

    !> Output prefix resolved against the deck's directory.
    function output_prefix(d) result(prefix)
        type(deck_t), intent(in) :: d
        character(len=:), allocatable :: prefix
        integer :: slash
        if (d%output(1:1) == '/') then
            prefix = d%output
        else
            slash = index(d%path, '/', back=.true.)
            prefix = d%path(:slash)//d%output
        end if
    end function output_prefix

    subroutine run_static(d, fl, st)
        type(deck_t), intent(in) :: d
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        type(chain_t) :: chain
        type(static_options_t) :: opts
        type(static_solution_t) :: sol
        real(dp), allocatable :: s(:), x(:), y(:), psi(:), moment(:)
        character(len=:), allocatable :: prefix
        integer :: i, j, n, unit, ios, ierr

        call chain_from_vector(d%nbeams, d%params, chain, st)
        if (st%code /= STATUS_OK) return
        if (d%tol > 0.0_dp) opts%tol = d%tol
        call solve_static(chain, d%load, d%wrt, opts, sol, st)
        if (st%code /= STATUS_OK) return
        n = d%shape_points
        allocate (s(n), x(n), y(n), psi(n), moment(n), stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(st, 'static', 'the shape table', 40.0_dp*real(n, dp))
            return
        end if
        if (n > 1) s = [(sum(chain%length)*real(i - 1, dp)/real(n - 1, dp), i = 1, n)]
        if (n > 1) then
            s(n) = sum(chain%length)
            call static_shape(chain, d%load, sol%unknowns, opts, s, x, y, psi, moment, st)
            if (st%code /= STATUS_OK) return
        end if

        prefix = output_prefix(d)
        call make_parent_folder(prefix, st)
        if (st%code /= STATUS_OK) return
        call open_output(fl, prefix//'_summary.csv', 'quantity,value', unit, ios, st)
        if (st%code /= STATUS_OK) return
        do i = 1, NOUT
            if (ios == 0) write (unit, '(a,",",es24.16e3)', iostat=ios) trim(output_names(i)), &
                sol%outputs(i)
        end do
        do j = 1, size(d%wrt)
            do i = 1, NOUT
                if (ios == 0) write (unit, '(a,",",es24.16e3)', iostat=ios) &
                    'd('//trim(output_names(i))//')/d('//param_name(d%nbeams, d%wrt(j))//')', &
                    sol%doutputs(i, j)
            end do
        end do
        if (ios == 0) write (unit, '(a,",",i0)', iostat=ios) 'newton_iterations', &
            sol%newton_iterations
        if (ios == 0) write (unit, '(a,",",i0)', iostat=ios) 'load_steps', sol%load_steps
        call close_checked(unit, ios, prefix//'_summary.csv', st)
        if (st%code /= STATUS_OK) return

        if (n < 2) return
        call open_output(fl, prefix//'_shape.csv', 's,x,y,psi,moment', unit, ios, st)
        if (st%code /= STATUS_OK) return
        do i = 1, n
            if (ios == 0) write (unit, '(4(es24.16e3,","),es24.16e3)', iostat=ios) &
                s(i), x(i), y(i), psi(i), moment(i)
        end do
        call close_checked(unit, ios, prefix//'_shape.csv', st)
    end subroutine run_static

    !> Finite element statics (docs/fe.md): tip values and the node table.
    subroutine run_fe_static(d, fl, st)
        type(deck_t), intent(in) :: d
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        type(fe_mesh_t) :: mesh
        type(fe_load_t) :: load
        type(fe_newton_opts_t) :: opts
        integer :: nnode, info(3)
        real(dp), allocatable :: nodes(:, :), guess(:, :), nodes_out(:, :), guess_out(:, :)
        real(dp) :: energy, reactions(3), residual
        character(len=:), allocatable :: prefix
        integer :: unit, ios, i, ierr
        real(dp) :: total, values(8)
        character(len=*), parameter :: names(8) = [character(len=8) :: 'w_tip', 'dw_tip', &
            'u_tip', 'du_tip', 'du_root', 'energy', 'x_tip', 'y_tip']

        nnode = d%nbeams*d%fe_elements_per_beam + 1
        allocate (nodes(5, nnode), guess(5, nnode), nodes_out(2, nnode), guess_out(2, nnode), &
                  stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(st, 'fe_static', 'the node tables', 112.0_dp*real(nnode, dp))
            return
        end if
        guess = 0.0_dp
        guess_out = 0.0_dp
        call fe_setup(d%nbeams, d%params, d%fe_elements_per_beam, [d%load%fx, d%load%fy, &
                      d%load%moment, real(d%fe_moment_form, dp)], d%fe_steps, d%fe_tol, mesh, &
                      load, opts, st)
        if (st%code == STATUS_OK) then
            call fe_static_nodes(mesh, load, .false., opts, guess, guess_out, nodes, nodes_out, &
                                 energy, reactions, residual, info, st)
        end if
        if (st%code /= STATUS_OK) return
        total = nodes(1, nnode)
        prefix = output_prefix(d)
        call make_parent_folder(prefix, st)
        if (st%code /= STATUS_OK) return
        call open_output(fl, prefix//'_summary.csv', 'quantity,value', unit, ios, st)
        if (st%code /= STATUS_OK) return
        values = [nodes(4, nnode), nodes(5, nnode), nodes(2, nnode), nodes(3, nnode), &
                  nodes(3, 1), energy, total + nodes(2, nnode), nodes(4, nnode)]
        do i = 1, size(names)
            if (ios == 0) write (unit, '(a,",",es24.16e3)', iostat=ios) trim(names(i)), &
                values(i)
        end do
        if (ios == 0) write (unit, '(a,",",i0)', iostat=ios) 'newton_iterations', info(1)
        if (ios == 0) write (unit, '(a,",",i0)', iostat=ios) 'load_steps', info(2)
        call close_checked(unit, ios, prefix//'_summary.csv', st)
        if (st%code /= STATUS_OK) return
        call open_output(fl, prefix//'_nodes.csv', 's,u,du,w,dw', unit, ios, st)
        if (st%code /= STATUS_OK) return
        do i = 1, nnode
            if (ios == 0) write (unit, '(4(es24.16e3,","),es24.16e3)', iostat=ios) nodes(:, i)
        end do
        call close_checked(unit, ios, prefix//'_nodes.csv', st)
    end subroutine run_fe_static

    !> Finite element linear modes: frequencies by family (Tables 9, 10).
    subroutine run_fe_modes(d, fl, st)
        type(deck_t), intent(in) :: d
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        type(fe_mesh_t) :: mesh
        integer :: nfree
        real(dp), allocatable :: omega(:), phi(:, :)
        integer, allocatable :: axial(:), dofs(:, :)
        character(len=:), allocatable :: prefix
        integer :: unit, ios, i, nw, nu, ierr

        ! four unknowns per node (six at a hinge); the clamp (Eq. 103) fixes u, w, w'
        call fe_mesh_from_params(d%nbeams, d%params, d%fe_elements_per_beam, mesh, st)
        if (st%code /= STATUS_OK) return
        nfree = mesh%nfree
        allocate (omega(nfree), phi(nfree, nfree), axial(nfree), dofs(2, nfree), stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(st, 'fe_modes', 'the mode shapes', 8.0_dp*real(nfree, dp)**2)
            return
        end if
        call fe_modes_table(mesh, d%fe_rotary_inertia, omega, phi, axial, dofs, st)
        if (st%code /= STATUS_OK) return
        prefix = output_prefix(d)
        call make_parent_folder(prefix, st)
        if (st%code /= STATUS_OK) return
        call open_output(fl, prefix//'_modes.csv', 'quantity,value', unit, ios, st)
        if (st%code /= STATUS_OK) return
        nw = 0
        nu = 0
        do i = 1, nfree
            if (axial(i) /= 0) then
                nu = nu + 1
                if (ios == 0) write (unit, '(a,i0,",",es24.16e3)', iostat=ios) 'omega_u', nu, &
                    omega(i)
            else
                nw = nw + 1
                if (ios == 0) write (unit, '(a,i0,",",es24.16e3)', iostat=ios) 'omega_w', nw, &
                    omega(i)
            end if
        end do
        call close_checked(unit, ios, prefix//'_modes.csv', st)
    end subroutine run_fe_modes

    ! -------------------------------------------------------------- dynamics

    !> Dynamic decks: release from the static shape under &load and integrate
    !! to the output times with release_response (the library routine behind
    !! beamid.simulate); <output>_history.csv has one row per output time
    !! (columns as beamid.decks.HISTORY_COLUMNS).
    subroutine run_simulate(d, fl, st)
        type(deck_t), intent(in) :: d
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        type(chain_t) :: chain
        type(release_spec_t) :: spec
        type(release_out_t) :: out
        real(dp), allocatable :: tip(:, :), ledger(:, :), work(:, :), torque(:)
        character(len=:), allocatable :: prefix, header, line
        integer :: unit, ios, k, i, nwork, nowrt(0)

        call chain_from_vector(d%nbeams, d%params, chain, st)
        if (st%code /= STATUS_OK) return
        spec%elements_per_beam = d%sim_elements_per_beam
        spec%load%fx = d%load%fx
        spec%load%fy = d%load%fy
        spec%load%moment = d%load%moment
        spec%motor_gain = d%sim_motor_gain
        spec%integrator = d%sim_integrator
        spec%friction = d%sim_friction
        spec%friction_velocity = d%sim_friction_velocity
        spec%dt = d%sim_dt
        spec%rtol = d%sim_rtol
        spec%atol = d%sim_atol
        call release_response(chain, spec, d%sim_t_out, nowrt, out, st)
        if (st%code /= STATUS_OK) return
        nwork = out%nwork
        tip = out%tip
        ledger = out%ledger
        work = out%hist%work
        torque = out%hist%torque

        header = 't,tip_u,tip_w,tip_angle,energy,kinetic,potential'
        do i = 1, nwork
            header = header//','//work_name(d%nbeams, i)
        end do
        header = header//',work,numerical,motor_torque'
        prefix = output_prefix(d)
        call make_parent_folder(prefix, st)
        if (st%code /= STATUS_OK) return
        call open_output(fl, prefix//'_history.csv', header, unit, ios, st)
        if (st%code /= STATUS_OK) return
        do k = 1, size(d%sim_t_out)
            line = fmt_e(d%sim_t_out(k))//','//fmt_e(tip(1, k))//','//fmt_e(tip(2, k))// &
                   ','//fmt_e(tip(3, k))//','//fmt_e(ledger(3, k))//','//fmt_e(ledger(1, k))// &
                   ','//fmt_e(ledger(2, k))
            do i = 1, nwork
                line = line//','//fmt_e(work(i, k))
            end do
            line = line//','//fmt_e(sum(work(:, k)))//','//fmt_e(ledger(4, k))//','// &
                   fmt_e(torque(k))
            call put(unit, ios, line)
        end do
        call close_checked(unit, ios, prefix//'_history.csv', st)
    end subroutine run_simulate

    !> Name of work line i of the ledger (beamid.dynamics.work_names):
    !! friction_<point>, drag_<point> per mass point, damping, motor.
    function work_name(nbeams, i) result(name)
        integer, intent(in) :: nbeams, i
        character(len=:), allocatable :: name
        integer :: k
        if (i > 2*nbeams) then
            name = merge('damping', 'motor  ', i == 2*nbeams + 1)
            name = trim(name)
            return
        end if
        k = mod(i - 1, nbeams) + 1
        name = merge('friction_', 'drag_    ', i <= nbeams)
        name = trim(name)
        if (k == nbeams) then
            name = name//'tip'
        else if (k == 1) then
            name = name//'elbow'
        else
            name = name//'joint'//fmt_int(k)
        end if
    end function work_name

    ! ------------------------------------------------------------ estimation

    !> Estimation decks: fit (and compare: the same files), diagnose, improve.
    !! Everything is computed first; the files are written after success.
    subroutine run_estimation(d, fl, st)
        type(deck_t), intent(in) :: d
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        type(fit_out_t) :: fo
        type(diag_out_t) :: dg
        character(len=:), allocatable :: prefix
        character(len=32), allocatable :: step_effect(:)
        real(dp), allocatable :: step_chi2(:), step_cpd(:), start(:)
        integer, allocatable :: step_dof(:)
        character(len=32) :: effect
        integer :: k, v, unit, ios

        call estimation_fit(d, d%params, d%free, fo, st)
        if (st%code /= STATUS_OK) return
        if (d%task == 'diagnose') then
            call estimation_diagnose(d, fo, dg, st)
            if (st%code /= STATUS_OK) return
        else if (d%task == 'improve') then
            ! fit, then diagnose and add the verdict's effect until none is
            ! significant (beamid.diagnosis.improve)
            allocate (step_effect(0), step_chi2(0), step_cpd(0), step_dof(0))
            effect = 'start'
            do k = 0, size(d%candidates)
                call estimation_diagnose(d, fo, dg, st)
                if (st%code /= STATUS_OK) return
                step_effect = [character(len=32) :: step_effect, effect]
                step_chi2 = [step_chi2, real(fo%stats(1), dp)]
                step_dof = [step_dof, nint(fo%stats(4))]
                step_cpd = [step_cpd, chi2_per_dof(fo)]
                v = nint(dg%dstats(1))
                if (v == 0 .or. k == size(d%candidates)) exit
                start = fo%params
                if (dg%cstats(7, v) /= 0.0_dp .and. dg%cstats(8, v) /= 0.0_dp) &
                    start = dg%refit_params(:, v)
                effect = d%candidates(v)
                call estimation_fit(d, start, [integer :: fo%free, &
                                    dg%cparams(dg%start(v):dg%start(v + 1) - 1)], fo, st)
                if (st%code /= STATUS_OK) return
            end do
        end if

        prefix = output_prefix(d)
        call make_parent_folder(prefix, st)
        if (st%code /= STATUS_OK) return
        call write_fit_files(d, fo, prefix, fl, st)
        if (st%code /= STATUS_OK) return
        if (d%task == 'diagnose' .or. d%task == 'improve') then
            call write_ranking(d, fo, dg, prefix//'_ranking.csv', fl, st)
            if (st%code /= STATUS_OK) return
        end if
        if (d%task == 'compare') then
            call write_compare(d, fo, prefix//'_compare.csv', fl, st)
            return
        end if
        if (d%task /= 'improve') return
        call open_output(fl, prefix//'_ladder.csv', 'step,effect,chi2,dof,chi2_per_dof', unit, ios, &
                         st)
        if (st%code /= STATUS_OK) return
        do k = 1, size(step_chi2)
            call put(unit, ios, fmt_int(k - 1)//','//trim(step_effect(k))//','// &
                     fmt_e(step_chi2(k))//','//fmt_int(step_dof(k))//','//fmt_e(step_cpd(k)))
        end do
        call close_checked(unit, ios, prefix//'_ladder.csv', st)
    end subroutine run_estimation

    !> A solver message '... (experiment k)' names the experiment and the deck
    !! instead: "... (experiment 'W13' of DECK)".
    subroutine name_experiment(d, st)
        type(deck_t), intent(in) :: d
        type(status_t), intent(inout) :: st
        integer :: at, close_, k, ios
        at = index(st%message, '(experiment ')
        if (at == 0) return
        close_ = index(st%message(at:), ')') + at - 1
        read (st%message(at + 12:close_ - 1), *, iostat=ios) k
        if (ios /= 0 .or. k < 1 .or. k > size(d%exp_names)) return
        st%message = st%message(:at - 1)//"(experiment '"//trim(d%exp_names(k))//"' of "// &
                     d%path//')'//st%message(close_ + 1:)
    end subroutine name_experiment

    !> compare: chi-square against its expectation, per-experiment chi-square and
    !! the residual structure tests (beamid_estimation residual_structure) with
    !! the load level of beamid.diagnosis.load_level: the force magnitude, else
    !! the moment magnitude, else for a wire the pull-in (total length - Lw).
    subroutine write_compare(d, fo, name, fl, st)
        type(deck_t), intent(in) :: d
        type(fit_out_t), intent(in) :: fo
        character(len=*), intent(in) :: name
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        real(dp), allocatable :: level(:), per_exp(:)
        real(dp) :: out(7), total, p, dof
        integer :: i, e, unit, ios
        logical :: systematic
        character(len=*), parameter :: test_names(7) = [character(len=13) :: 'runs', &
            'runs_expected', 'runs_z', 'runs_p', 'trend_slope', 'trend_z', 'trend_p']

        total = sum(d%params([(param_index_beam(d%nbeams, i, IB_L), i = 1, d%nbeams)]))
        allocate (level(size(d%row_exp)), per_exp(size(d%experiments)))
        per_exp = 0.0_dp
        do i = 1, size(d%row_exp)
            e = d%row_exp(i)
            associate (x => d%experiments(e))
                if (x%kind == LOAD_WIRE) then
                    level(i) = total - x%wire_length
                else if (hypot(x%fx, x%fy) > 0.0_dp) then
                    level(i) = hypot(x%fx, x%fy)
                else
                    level(i) = abs(x%moment)
                end if
            end associate
            per_exp(e) = per_exp(e) + fo%norm(i)**2
        end do
        call residual_structure(level, d%data%quantity, real(fo%norm, dp), out)
        dof = fo%stats(4)
        p = ieee_value(1.0_dp, ieee_quiet_nan)
        if (nint(dof) > 0) p = chi2_sf(fo%stats(1) + fo%stats(2), nint(dof))
        systematic = (p < 0.01_dp) .or. (out(4) < 0.01_dp) .or. (out(7) < 0.01_dp)
        call open_output(fl, name, 'quantity,value', unit, ios, st)
        if (st%code /= STATUS_OK) return
        call put(unit, ios, 'chi2,'//fmt_e(fo%stats(1)))
        call put(unit, ios, 'dof,'//fmt_int(nint(dof)))
        call put(unit, ios, 'expected,'//fmt_e(dof))
        call put(unit, ios, 'expected_sigma,'//fmt_e(sqrt(2.0_dp*max(dof, 0.0_dp))))
        call put(unit, ios, 'p_value,'//fmt_e(p))
        do i = 1, 7
            call put(unit, ios, trim(test_names(i))//','//fmt_e(out(i)))
        end do
        call put(unit, ios, 'systematic,'//trim(merge('1', '0', systematic)))
        do e = 1, size(d%experiments)
            call put(unit, ios, 'chi2['//trim(d%exp_names(e))//'],'//fmt_e(per_exp(e)))
        end do
        call close_checked(unit, ios, name, st)
    end subroutine write_compare

    !> (chi2 + chi2_prior) / dof, NaN without degrees of freedom.
    real(dp) function chi2_per_dof(fo)
        type(fit_out_t), intent(in) :: fo
        chi2_per_dof = ieee_value(1.0_dp, ieee_quiet_nan)
        if (nint(fo%stats(4)) > 0) chi2_per_dof = (fo%stats(1) + fo%stats(2))/fo%stats(4)
    end function chi2_per_dof

    !> The problem arrays of the f2py API (beamid_api_estimation).
    subroutine problem_arrays(d, exp_kind, exp_values, row_q)
        type(deck_t), intent(in) :: d
        integer(c_int), allocatable, intent(out) :: exp_kind(:), row_q(:)
        real(c_double), allocatable, intent(out) :: exp_values(:, :)
        integer :: e
        allocate (exp_kind(size(d%experiments)), exp_values(4, size(d%experiments)))
        do e = 1, size(d%experiments)
            exp_kind(e) = int(d%experiments(e)%kind, c_int)
            exp_values(:, e) = [d%experiments(e)%fx, d%experiments(e)%fy, &
                                d%experiments(e)%moment, d%experiments(e)%wire_length]
        end do
        row_q = int(d%data%quantity, c_int)
    end subroutine problem_arrays

    !> Weighted GN/LM fit of the free parameters from params0 (api_fit).
    subroutine estimation_fit(d, params0, free, fo, st)
        type(deck_t), intent(in) :: d
        real(dp), intent(in) :: params0(:)
        integer, intent(in) :: free(:)
        type(fit_out_t), intent(out) :: fo
        type(status_t), intent(inout) :: st
        integer(c_int), allocatable :: exp_kind(:), row_q(:)
        real(c_double), allocatable :: exp_values(:, :), corr(:, :), log1(:), log2(:), log3(:)
        real(c_double), allocatable :: logp(:, :)
        integer(c_int) :: code
        character(len=256) :: message
        integer :: nf, nrow, np

        call problem_arrays(d, exp_kind, exp_values, row_q)
        nf = size(free)
        nrow = size(d%row_exp)
        np = size(d%prior_index)
        fo%free = int(free, c_int)
        allocate (fo%params(size(params0)), fo%sigmas(nf), fo%cov(nf, nf), corr(nf, nf), &
                  fo%flags(nf), fo%pred(nrow), fo%norm(nrow), log1(d%max_iter + 1), &
                  log2(d%max_iter + 1), log3(d%max_iter + 1), logp(nf, d%max_iter + 1))
        call api_fit(int(d%nbeams, c_int), int(size(params0), c_int), params0, int(nf, c_int), &
                     fo%free, int(np, c_int), [int(d%prior_index, c_int), 0_c_int], &
                     [d%prior_mean, 0.0_dp], [d%prior_sigma, 0.0_dp], &
                     int(size(exp_kind), c_int), exp_kind, exp_values, int(nrow, c_int), &
                     int(d%row_exp, c_int), row_q, d%data%value, d%data%sigma, 0.0_c_double, &
                     int(d%max_iter, c_int), 0.0_c_double, 0.0_c_double, fo%params, fo%sigmas, &
                     fo%cov, corr, fo%flags, fo%pred, fo%norm, fo%stats, log1, log2, log3, &
                     logp, code, message)
        if (code /= 0) then
            call set_status(st, int(code), 'fit', trim(message))
            st%message = message
        end if
    end subroutine estimation_fit

    !> Score tests, refits and ranking of the deck's candidates around a fit
    !! (api_diagnose with the defaults of beamid.diagnose: 3 refits,
    !! ambiguity 4, collinearity 0.98, 50 iterations).
    subroutine estimation_diagnose(d, fo, dg, st)
        type(deck_t), intent(in) :: d
        type(fit_out_t), intent(in) :: fo
        type(diag_out_t), intent(out) :: dg
        type(status_t), intent(inout) :: st
        integer(c_int), allocatable :: exp_kind(:), row_q(:), block(:)
        real(c_double), allocatable :: exp_values(:, :), cosine(:, :)
        integer(c_int) :: code
        character(len=256) :: message
        integer :: c, nc, ncp, nrow, np

        call problem_arrays(d, exp_kind, exp_values, row_q)
        nc = size(d%candidates)
        allocate (dg%start(nc + 1), dg%cparams(0))
        dg%start(1) = 1
        do c = 1, nc
            call static_effect_params(d%nbeams, d%candidates(c), block, st)
            if (st%code /= STATUS_OK) return
            dg%cparams = [dg%cparams, block]
            dg%start(c + 1) = dg%start(c) + size(block)
        end do
        ncp = size(dg%cparams)
        nrow = size(d%row_exp)
        np = size(d%prior_index)
        allocate (dg%cstats(18, nc), dg%pstats(6, ncp + 1), dg%refit_params(size(fo%params), nc), &
                  dg%ranking(nc), cosine(nc, nc))
        call api_diagnose(int(d%nbeams, c_int), int(size(fo%params), c_int), fo%params, &
                          int(size(fo%free), c_int), fo%free, int(np, c_int), &
                          [int(d%prior_index, c_int), 0_c_int], [d%prior_mean, 0.0_dp], &
                          [d%prior_sigma, 0.0_dp], int(size(exp_kind), c_int), exp_kind, &
                          exp_values, int(nrow, c_int), int(d%row_exp, c_int), row_q, &
                          d%data%value, d%data%sigma, 0.0_c_double, 50_c_int, 0.0_c_double, &
                          0.0_c_double, int(nc, c_int), dg%start, int(ncp, c_int), &
                          [dg%cparams, 0_c_int], d%alpha, 3_c_int, 4.0_c_double, 0.98_c_double, &
                          dg%cstats, dg%pstats, dg%refit_params, dg%ranking, cosine, dg%dstats, &
                          code, message)
        if (code /= 0) then
            call set_status(st, int(code), 'diagnose', trim(message))
            st%message = message
        end if
    end subroutine estimation_diagnose

    !> <prefix>_estimates.csv, _covariance.csv and _residuals.csv.
    subroutine write_fit_files(d, fo, prefix, fl, st)
        type(deck_t), intent(in) :: d
        type(fit_out_t), intent(in) :: fo
        character(len=*), intent(in) :: prefix
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        character(len=:), allocatable :: line
        integer :: unit, ios, i, j, r

        call open_output(fl, prefix//'_estimates.csv', 'name,estimate,sigma,flag', unit, ios, st)
        if (st%code /= STATUS_OK) return
        do i = 1, size(fo%free)
            call put(unit, ios, param_name(d%nbeams, fo%free(i))//','// &
                     fmt_e(fo%params(fo%free(i)))//','//fmt_e(fo%sigmas(i))//','// &
                     trim(flag_text(min(max(fo%flags(i), 0), 4))))
        end do
        call put(unit, ios, 'chi2,'//fmt_e(fo%stats(1))//',,')
        call put(unit, ios, 'chi2_prior,'//fmt_e(fo%stats(2))//',,')
        call put(unit, ios, 'dof,'//fmt_int(nint(fo%stats(4)))//',,')
        call put(unit, ios, 'iterations,'//fmt_int(nint(fo%stats(6)))//',,')
        call put(unit, ios, 'condition_number,'//fmt_e(fo%stats(3))//',,')
        call close_checked(unit, ios, prefix//'_estimates.csv', st)
        if (st%code /= STATUS_OK) return

        line = 'name'
        do i = 1, size(fo%free)
            line = line//','//param_name(d%nbeams, fo%free(i))
        end do
        call open_output(fl, prefix//'_covariance.csv', line, unit, ios, st)
        if (st%code /= STATUS_OK) return
        do i = 1, size(fo%free)
            line = param_name(d%nbeams, fo%free(i))
            do j = 1, size(fo%free)
                line = line//','//fmt_e(fo%cov(i, j))
            end do
            call put(unit, ios, line)
        end do
        call close_checked(unit, ios, prefix//'_covariance.csv', st)
        if (st%code /= STATUS_OK) return

        call open_output(fl, prefix//'_residuals.csv', &
                         'experiment,t,quantity,measured,model,sigma,normalized', unit, ios, st)
        if (st%code /= STATUS_OK) return
        do r = 1, size(d%row_exp)
            call put(unit, ios, trim(d%data%experiment(r))//','//fmt_g(d%data%t(r))//','// &
                     quantity_label(d%data%quantity(r))//','//fmt_e(d%data%value(r))//','// &
                     fmt_e(fo%pred(r))//','//fmt_e(d%data%sigma(r))//','//fmt_e(fo%norm(r)))
        end do
        call close_checked(unit, ios, prefix//'_residuals.csv', st)
    end subroutine write_fit_files

    !> <prefix>_ranking.csv: candidates best first, one row per parameter
    !! (columns as beamid.fit_decks.write_ranking). The drop, p-value,
    !! estimate and sigma are the refit's when one was made, else the score
    !! test's (first order).
    subroutine write_ranking(d, fo, dg, name, fl, st)
        type(deck_t), intent(in) :: d
        type(fit_out_t), intent(in) :: fo
        type(diag_out_t), intent(in) :: dg
        character(len=*), intent(in) :: name
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        real(dp) :: nan, score_drop, score_p, lr_drop, lr_p, drop, p, est, sig
        logical :: tested, refit
        integer :: unit, ios, rank, c, j, k, nj, state
        character(len=:), allocatable :: pname, flags

        nan = ieee_value(1.0_dp, ieee_quiet_nan)
        call open_output(fl, name, 'rank,effect,state,parameter,score_drop,score_p,refit_drop,'// &
                         'refit_p,chi2_drop,p_value,estimate,sigma,physical,identifiable,'// &
                         'significant,acceptable,rival', unit, ios, st)
        if (st%code /= STATUS_OK) return
        do rank = 1, size(dg%ranking)
            c = dg%ranking(rank)
            associate (cs => dg%cstats(:, c))
                state = nint(cs(1))
                tested = state == 0
                refit = tested .and. cs(7) /= 0.0_dp .and. cs(8) /= 0.0_dp
                score_drop = merge(cs(2), nan, tested)
                score_p = merge(cs(3), nan, tested)
                lr_drop = merge(cs(9), nan, refit)
                lr_p = merge(cs(10), nan, refit)
                drop = score_drop
                p = score_p
                if (refit .and. .not. ieee_is_nan(lr_drop)) drop = lr_drop
                if (refit .and. .not. ieee_is_nan(lr_p)) p = lr_p
                if (tested) then
                    flags = b2s(cs(5))//','//b2s(cs(6))//','//b2s(cs(11))//','//b2s(cs(12))// &
                            ','//b2s(cs(13))
                else
                    flags = '1,1,0,0,0'
                end if
                nj = dg%start(c + 1) - dg%start(c)
                do j = 1, max(nj, 1)
                    pname = ''
                    est = nan
                    sig = nan
                    if (nj > 0) then
                        k = dg%start(c) + j - 1
                        pname = param_name(d%nbeams, dg%cparams(k))
                        if (refit) then
                            est = dg%pstats(4, k)
                            sig = dg%pstats(5, k)
                        else if (tested) then
                            est = fo%params(dg%cparams(k)) + dg%pstats(1, k)
                            sig = dg%pstats(2, k)
                        end if
                    end if
                    call put(unit, ios, fmt_int(rank)//','//trim(d%candidates(c))//','// &
                             trim(state_text(state))//','//pname//','//fmt_e(score_drop)//','// &
                             fmt_e(score_p)//','//fmt_e(lr_drop)//','//fmt_e(lr_p)//','// &
                             fmt_e(drop)//','//fmt_e(p)//','//fmt_e(est)//','//fmt_e(sig)//','// &
                             flags)
                end do
            end associate
        end do
        call close_checked(unit, ios, name, st)
    end subroutine write_ranking

    !> A 0/1 flag of the API as '0' or '1'.
    pure function b2s(x) result(text)
        real(c_double), intent(in) :: x
        character(len=1) :: text
        text = merge('1', '0', x /= 0.0_c_double)
    end function b2s

    !> Write one line unless an earlier write failed.
    subroutine put(unit, ios, text)
        integer, intent(in) :: unit
        integer, intent(inout) :: ios
        character(len=*), intent(in) :: text
        if (ios == 0) write (unit, '(a)', iostat=ios) text
    end subroutine put

    !> A real as Python's format(x, '.16E') writes it (17 significant digits,
    !! two exponent digits unless three are needed; NaN, Infinity, -Infinity).
    function fmt_e(x) result(text)
        real(dp), intent(in) :: x
        character(len=:), allocatable :: text
        character(len=32) :: buffer
        integer :: e
        write (buffer, '(es24.16e3)') x
        text = trim(adjustl(buffer))
        e = index(text, 'E')
        if (e > 0 .and. len(text) == e + 4) then
            if (text(e + 2:e + 2) == '0') text = text(:e + 1)//text(e + 3:)
        end if
    end function fmt_e

    !> Create the folder that will hold files starting with `prefix`.
    subroutine make_parent_folder(prefix, st)
        character(len=*), intent(in) :: prefix
        type(status_t), intent(inout) :: st
        integer :: slash, exitstat, cmdstat
        logical :: exists
        slash = index(prefix, '/', back=.true.)
        if (slash <= 1) return
        inquire (file=prefix(:slash - 1)//'/.', exist=exists)
        if (exists) return
        if (index(prefix, "'") > 0) then
            call set_status(st, ERR_OUTPUT, 'output', 'cannot create the folder of '// &
                            prefix//' (a path with a quote)')
            return
        end if
        call execute_command_line("mkdir -p '"//prefix(:slash - 1)//"' 2>/dev/null", &
                                  exitstat=exitstat, cmdstat=cmdstat)
        if (cmdstat /= 0 .or. exitstat /= 0) call set_status(st, ERR_OUTPUT, 'output', &
            'cannot create the output folder '//prefix(:slash - 1)// &
            ' (a file of that name, or no permission)')
    end subroutine make_parent_folder

    !> Open an output file under its temporary name and write its header line.
    subroutine open_output(fl, name, header, unit, ios, st)
        type(files_t), intent(inout) :: fl
        character(len=*), intent(in) :: name, header
        integer, intent(out) :: unit, ios
        type(status_t), intent(inout) :: st
        character(len=512) :: msg
        open (newunit=unit, file=name//TMP_SUFFIX, status='replace', action='write', &
              iostat=ios, iomsg=msg)
        if (ios /= 0) then
            call set_status(st, ERR_OUTPUT, 'output', 'cannot write '//name//': '//trim(msg))
            return
        end if
        fl%names = fl%names//name//new_line('a')
        write (unit, '(a)', iostat=ios) header
    end subroutine open_output

    !> Close a written file; a failed write is an error naming the file.
    subroutine close_checked(unit, ios, name, st)
        integer, intent(in) :: unit, ios
        character(len=*), intent(in) :: name
        type(status_t), intent(inout) :: st
        integer :: ios_close
        close (unit, iostat=ios_close)
        if (ios /= 0 .or. ios_close /= 0) call set_status(st, ERR_OUTPUT, 'output', &
            'writing '//name//' failed (disk full or no permission)')
    end subroutine close_checked

    !> All or nothing: rename every temporary file to its final name when the
    !! run succeeded, else (or when a rename fails) remove the temporary files
    !! and the files already renamed.
    subroutine finish_files(fl, st)
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        integer :: start, nl, k, done
        character(len=:), allocatable :: name
        integer(c_int) :: rc
        logical :: isdir

        done = 0
        if (st%code == STATUS_OK) then
            start = 1
            do while (start <= len(fl%names))
                nl = index(fl%names(start:), new_line('a'))
                name = fl%names(start:start + nl - 2)
                inquire (file=name//'/.', exist=isdir)
                if (isdir) then
                    call set_status(st, ERR_OUTPUT, 'output', 'cannot write '//name// &
                                    ': it is a directory')
                    exit
                end if
                rc = c_rename(cstr(name//TMP_SUFFIX), cstr(name))
                if (rc /= 0) then
                    call set_status(st, ERR_OUTPUT, 'output', 'cannot write '//name)
                    exit
                end if
                done = done + 1
                start = start + nl
            end do
        end if
        if (st%code == STATUS_OK) return
        ! remove what this run wrote: renamed files and temporary ones
        start = 1
        k = 0
        do while (start <= len(fl%names))
            nl = index(fl%names(start:), new_line('a'))
            name = fl%names(start:start + nl - 2)
            k = k + 1
            if (k <= done) then
                rc = c_remove(cstr(name))
            else
                rc = c_remove(cstr(name//TMP_SUFFIX))
            end if
            start = start + nl
        end do
        fl%names = ''
    end subroutine finish_files

    !> A NUL-terminated copy of a Fortran string for C.
    pure function cstr(text) result(c)
        character(len=*), intent(in) :: text
        character(kind=c_char) :: c(len(text) + 1)
        integer :: i
        do i = 1, len(text)
            c(i) = text(i:i)
        end do
        c(len(text) + 1) = c_null_char
    end function cstr
end module beamid_tasks
