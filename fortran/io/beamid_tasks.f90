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
    use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_nan, &
                                             ieee_positive_inf, ieee_is_finite
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK, ERR_OUTPUT, ERR_INPUT, set_status, fmt_int, &
                             set_alloc_error, fmt_real
    use beamid_model, only: chain_t, chain_from_vector, param_name, param_index_beam, IB_L, &
                            param_count
    use beamid_deck, only: deck_t, stage_t, take_stage, FRICTION_LAWS
    use beamid_arclength, only: static_options_t, static_solution_t, solve_static, LOAD_WIRE, &
                                static_shape, NOUT
    use beamid_fe_assembly, only: fe_mesh_t, fe_load_t
    use beamid_fe_static, only: fe_newton_opts_t
    use beamid_fe_nodes, only: fe_mesh_from_params, fe_setup, fe_static_nodes, fe_modes_table
    ! Every driver is a library call, as the f2py layer makes it: finite
    ! elements (beamid_fe_nodes), dynamics (beamid_release) and estimation
    ! (beamid_inverse).
    use beamid_release, only: release_spec_t, release_out_t, release_response
    use beamid_loads, only: histories_from_columns, HIST_CHIRP
    use beamid_dynamics, only: dyn_work_name
    use beamid_estimation, only: residual_structure, chi2_sf, fit_result_t, prior_t, &
                                 candidate_t, FLAG_NAMES, CAND_NAMES, prior_from_covariance, &
                                 STOP_NAMES, FLAG_OK
    use beamid_inverse, only: experiment_spec_t, EV_FX, EV_FY, EV_MOMENT, EV_WIRE_LENGTH, &
                              EV_NEPB, chain_layout, NU_T0, NU_BIAS, NU_SCALE, NU_V0
    use beamid_chain_deck, only: chain_asked, ordered_observations
    use beamid_ladder, only: problem_t, cand_set_t, diag_out_t, rung_t, &
                             ladder_t, ladder_start, ladder_step, ladder_end_at_fit
    use beamid_observations, only: obs_label, obs_groups, observation_t, same_observation
    use beamid_dyn_diagnosis, only: has_mesh
    use beamid_family, only: SPEC_KEYS
    use beamid_effects, only: effect_params
    use beamid_measurements, only: fmt_g
    implicit none
    private

    public :: run_task, files_t, deck_problem, deck_candidates, deck_ladder_start
    public :: deck_stage_start, deck_experiments, deck_specs, name_experiment, deck_warnings

    !> The files of one run: final names, newline separated, in write order;
    !! each is `prefix` (the deck's output resolved against its directory)
    !! and a suffix; `last` is the one open. The prefix's folder is made at
    !! the first open, after the computation succeeded.
    type :: files_t
        character(len=:), allocatable :: names, prefix, last
        logical :: folder_ok = .false.
        !> One line saying what the run found (printed by both programs
        !! before the files; run_task's `summary`)
        character(len=:), allocatable :: summary
    end type files_t

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
    !! `ladder`: an estimation deck's rungs when already run (deck_ladder_start
    !! and ladder_step, or an identify deck's stages, deck_stage_start, as
    !! beamid.run steps them from Python): only the files are written.
    subroutine run_task(deck, written, stat, ladder, summary)
        type(deck_t), intent(in) :: deck
        character(len=:), allocatable, intent(out) :: written
        type(status_t), intent(inout) :: stat
        type(rung_t), intent(in), optional :: ladder(:)
        !> one line: the deck's path and what the run found (the same line from
        !! beamid-batch and beamid run, before the files written)
        character(len=:), allocatable, intent(out), optional :: summary
        type(files_t) :: fl
        integer :: slash
        fl%names = ''
        fl%summary = ''
        written = ''
        if (present(summary)) summary = ''
        fl%prefix = deck%output
        slash = index(deck%path, '/', back=.true.)
        if (index(deck%output, '/') /= 1) fl%prefix = deck%path(:slash)//deck%output
        select case (deck%task)
        case ('fe_static')
            call run_fe_static(deck, fl, stat)
        case ('fe_modes')
            call run_fe_modes(deck, fl, stat)
        case ('fit', 'compare', 'diagnose', 'improve')
            call run_estimation(deck, fl, stat, ladder)
        case ('identify')
            call run_identify(deck, fl, stat, ladder)
        case ('simulate')
            call run_simulate(deck, fl, stat)
        case default
            call run_static(deck, fl, stat)
        end select
        if (stat%code /= STATUS_OK .and. allocated(deck%exp_names)) call name_experiment(deck, stat)
        call finish_files(fl, stat)
        if (stat%code == STATUS_OK) written = fl%names
        if (stat%code == STATUS_OK .and. present(summary)) summary = deck%path//': '//fl%summary
    end subroutine run_task

    !> x with `d` decimals and a leading zero (Python's f'{x:.{d}f}').
    function fixed(x, d) result(text)
        real(dp), intent(in) :: x
        integer, intent(in) :: d
        character(len=:), allocatable :: text
        character(len=64) :: buffer
        if (.not. ieee_is_finite(x)) then
            text = fmt_real(x)
            return
        end if
        write (buffer, '(f0.'//fmt_int(d)//')') x
        text = trim(adjustl(buffer))
        if (text(1:1) == '.') text = '0'//text
        if (text(1:min(2, len(text))) == '-.') text = '-0'//text(2:)
    end function fixed

    !> x in at most six significant digits, no trailing zeros (as Python's
    !! f'{x:g}', but for the exponent's form: 1.97321e-020).
    function short(x) result(text)
        real(dp), intent(in) :: x
        character(len=:), allocatable :: text
        character(len=32) :: buffer
        integer :: d, e
        if (.not. ieee_is_finite(x) .or. x == 0.0_dp) then
            text = merge('0  ', fmt_real(x), x == 0.0_dp)
            text = trim(text)
            return
        end if
        if (abs(x) < 1.0e-3_dp .or. abs(x) >= 1.0e7_dp) then
            ! mantissa of six digits without trailing zeros, then the exponent
            write (buffer, '(es0.5e0)') x
            e = index(buffer, 'E')
            text = trim(adjustl(buffer(:e - 1)))
            do while (text(len(text):len(text)) == '0')
                text = text(:len(text) - 1)
            end do
            if (text(len(text):len(text)) == '.') text = text(:len(text) - 1)
            text = text//'e'//trim(adjustl(buffer(e + 1:)))
            return
        end if
        d = max(0, 5 - floor(log10(abs(x))))
        text = fixed(x, d)
        if (index(text, '.') > 0) then
            do while (text(len(text):len(text)) == '0')
                text = text(:len(text) - 1)
            end do
            if (text(len(text):len(text)) == '.') text = text(:len(text) - 1)
        end if
    end function short

    !> The summary of a fit: how it ended, chi-square, flagged parameters.
    function fit_line(d, f) result(text)
        type(deck_t), intent(in) :: d
        type(fit_result_t), intent(in) :: f
        character(len=:), allocatable :: text, flagged
        integer :: i
        text = trim(STOP_NAMES(min(max(f%stop, 0), ubound(STOP_NAMES, 1))))//' after '// &
               fmt_int(f%iterations)//' iterations, chi2 '//short(f%chi2)//' for '// &
               fmt_int(f%dof)//' dof'
        flagged = ''
        do i = 1, size(f%free)
            if (f%flags(i) == FLAG_OK) cycle
            if (len(flagged) > 0) flagged = flagged//', '
            flagged = flagged//deck_param_name(d, f%free(i))//' '// &
                      trim(FLAG_NAMES(min(max(f%flags(i), 0), ubound(FLAG_NAMES, 1))))
        end do
        if (len(flagged) > 0) text = text//'; flagged: '//flagged
    end function fit_line

    !> The folder that will hold the files starting with `prefix` created.
    subroutine make_folder(prefix, st)
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
    end subroutine make_folder

    subroutine run_static(d, fl, st)
        type(deck_t), intent(in) :: d
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        type(chain_t) :: chain
        type(static_options_t) :: opts
        type(static_solution_t) :: sol
        real(dp), allocatable :: s(:), x(:), y(:), psi(:), moment(:)
        character(len=64), allocatable :: names(:)
        integer :: i, j, n, ierr

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

        names = [(output_names(i), i=1, NOUT)]
        do j = 1, size(d%wrt)
            names = [character(len=64) :: names, ('d('//trim(output_names(i))//')/d('// &
                     param_name(d%nbeams, d%wrt(j))//')', i=1, NOUT)]
        end do
        fl%summary = 'tip ('//fixed(sol%outputs(1), 6)//', '//fixed(sol%outputs(2), 6)// &
                     ') m, angle '//fixed(sol%outputs(3), 6)//' rad'
        if (d%load%kind == LOAD_WIRE) fl%summary = fl%summary//', wire force '// &
            fixed(sol%outputs(4), 4)//' N'
        call write_summary(fl, '_summary.csv', names, [sol%outputs, sol%doutputs], &
                           [sol%newton_iterations, sol%load_steps], st)
        if (st%code /= STATUS_OK .or. n < 2) return
        call write_table(fl, '_shape.csv', 's,x,y,psi,moment', &
                         transpose(reshape([s, x, y, psi, moment], [n, 5])), st)
    end subroutine run_static

    !> Finite element statics (docs/fe.md): tip values and the node table.
    subroutine run_fe_static(d, fl, st)
        type(deck_t), intent(in) :: d
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        type(fe_mesh_t) :: mesh
        type(fe_load_t) :: load
        type(fe_newton_opts_t) :: opts
        integer :: nnode, info(3), ierr
        real(dp), allocatable :: nodes(:, :), guess(:, :), nodes_out(:, :), guess_out(:, :)
        real(dp) :: energy, reactions(3), residual
        character(len=*), parameter :: names(8) = [character(len=8) :: 'w_tip', 'dw_tip', &
            'u_tip', 'du_tip', 'du_root', 'energy', 'x_tip', 'y_tip']

        nnode = d%nbeams*d%fe_elements_per_beam + 1
        allocate (nodes(5, nnode), guess(5, nnode), nodes_out(2, nnode), guess_out(2, nnode), &
                  source=0.0_dp, stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(st, 'fe_static', 'the node tables', 112.0_dp*real(nnode, dp))
            return
        end if
        call fe_setup(d%nbeams, d%params, d%fe_elements_per_beam, [d%load%fx, d%load%fy, &
                      d%load%moment, real(d%fe_moment_form, dp)], d%fe_steps, d%fe_tol, mesh, &
                      load, opts, st)
        if (st%code == STATUS_OK) then
            call fe_static_nodes(mesh, load, .false., opts, guess, guess_out, nodes, nodes_out, &
                                 energy, reactions, residual, info, st)
        end if
        if (st%code /= STATUS_OK) return
        fl%summary = 'fe_static, '//fmt_int(d%nbeams*d%fe_elements_per_beam)// &
            ' elements: tip w '//fixed(nodes(4, nnode), 6)//' m, u '//fixed(nodes(2, nnode), 6)// &
            ' m, energy '//fixed(energy, 6)//' N m'
        call write_summary(fl, '_summary.csv', names, [nodes(4, nnode), &
                           nodes(5, nnode), nodes(2, nnode), nodes(3, nnode), nodes(3, 1), energy, &
                           nodes(1, nnode) + nodes(2, nnode), nodes(4, nnode)], info(1:2), st)
        if (st%code /= STATUS_OK) return
        call write_table(fl, '_nodes.csv', 's,u,du,w,dw', nodes, st)
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
        call open_output(fl, '_modes.csv', 'quantity,value', unit, ios, st)
        if (st%code /= STATUS_OK) return
        nw = 0
        nu = 0
        do i = 1, nfree
            ! the axial and the bending family numbered apart
            if (axial(i) /= 0) nu = nu + 1
            if (axial(i) == 0) nw = nw + 1
            if (ios == 0) write (unit, '(a,i0,",",es24.16e3)', iostat=ios) &
                merge('omega_u', 'omega_w', axial(i) /= 0), merge(nu, nw, axial(i) /= 0), omega(i)
        end do
        call close_checked(fl, unit, ios, st)
        fl%summary = 'fe_modes, '//fmt_int(d%nbeams*d%fe_elements_per_beam)//' elements: '// &
            fmt_int(nw)//' transverse and '//fmt_int(nu)//' axial frequencies, the lowest '// &
            short(minval(omega))//' rad/s'
    end subroutine run_fe_modes

    !> Warnings about a deck that is valid but asks something the model cannot
    !! give (one per line, '' for none; the library does not print them,
    !! beamid-batch writes them to stderr, beamid.simulate and the fits warn
    !! in Python alike): a chirp of a &history group reaching above the
    !! highest frequency of the mesh its experiment runs on (the linear
    !! modes of fe_modes_table without rotary inertia, as
    !! beamid.dynamics._warn_chirp), where the response is the mesh's.
    function deck_warnings(d) result(text)
        type(deck_t), intent(in) :: d
        character(len=:), allocatable :: text
        type(fe_mesh_t) :: mesh
        type(status_t) :: st
        real(dp), allocatable :: omega(:), phi(:, :)
        type(experiment_spec_t), allocatable :: specs(:)
        integer, allocatable :: axial(:), dofs(:, :), kinds(:)
        real(dp) :: top, fmax
        integer :: k, e, nepb
        text = ''
        if (.not. allocated(d%hist%spec)) return
        do k = 1, size(d%hist%spec, 2)
            if (nint(d%hist%spec(3, k)) /= HIST_CHIRP) cycle
            top = max(d%hist%spec(7, k), d%hist%spec(8, k))
            e = nint(d%hist%spec(1, k))
            if (d%task == 'simulate') then
                nepb = d%sim_elements_per_beam
            else
                call deck_experiments(d, kinds, specs)
                if (e < 1 .or. e > size(kinds)) cycle
                nepb = specs(e)%get_int(EV_NEPB)
            end if
            call fe_mesh_from_params(d%nbeams, d%params, nepb, mesh, st)
            if (st%code /= STATUS_OK) cycle
            if (allocated(omega)) deallocate (omega, phi, axial, dofs)
            allocate (omega(mesh%nfree), phi(mesh%nfree, mesh%nfree), axial(mesh%nfree), &
                      dofs(2, mesh%nfree))
            call fe_modes_table(mesh, .false., omega, phi, axial, dofs, st)
            if (st%code /= STATUS_OK) cycle
            fmax = maxval(omega)/(2.0_dp*acos(-1.0_dp))
            if (top > fmax) text = text//d%path//': &history '//fmt_int(k)//': a chirp '// &
                'reaches '//short(top)//' Hz, above the highest frequency of the mesh ('// &
                short(fmax)//' Hz at elements_per_beam = '//fmt_int(nepb)//'): the response '// &
                'there is the mesh''s, not the arm''s'//new_line('a')
        end do
    end function deck_warnings

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
        type(release_out_t) :: out
        type(release_spec_t) :: spec
        character(len=:), allocatable :: header, line
        integer :: unit, ios, k, i, nwork, nowrt(0), nbase
        real(dp) :: hub(2)

        call chain_from_vector(d%nbeams, d%params, chain, st)
        if (st%code /= STATUS_OK) return
        spec = release_spec_t(elements_per_beam=d%sim_elements_per_beam, &
            load=fe_load_t(d%load%fx, d%load%fy, d%load%moment), motor_gain=d%sim_motor_gain, &
            integrator=d%sim_integrator, rtol=d%sim_rtol, atol=d%sim_atol, dt=d%sim_dt, &
            friction=d%sim_friction, friction_velocity=d%sim_friction_velocity)
        ! the deck's &history groups (experiment 1 of its list)
        if (allocated(d%hist%spec)) then
            if (size(d%hist%spec, 2) > 0) then
                call histories_from_columns(d%hist%spec(2:, :), d%hist%tab, spec%histories, &
                                            st, hub, spec%hub, spec%hub_table)
                if (st%code /= STATUS_OK) return
                spec%hub_ws = hub(1)
                spec%hub_period = hub(2)
            end if
        end if
        call release_response(chain, spec, d%sim_t_out, nowrt, out, st)
        if (st%code /= STATUS_OK) return
        nwork = out%nwork

        header = 't,tip_u,tip_w,tip_angle,energy,kinetic,potential'
        ! the chain's work lines, then the histories' (named by their targets)
        ! and the hub's
        nbase = nwork
        if (allocated(spec%histories)) nbase = nbase - size(spec%histories)
        if (spec%hub) nbase = nbase - 1
        do i = 1, nbase
            header = header//','//dyn_work_name(d%nbeams, i)
        end do
        if (allocated(spec%histories)) then
            do i = 1, size(spec%histories)
                header = header//','//trim(spec%histories(i)%name)
            end do
        end if
        if (spec%hub) header = header//',hub'
        header = header//',work,numerical,motor_torque'
        call open_output(fl, '_history.csv', header, unit, ios, st)
        if (st%code /= STATUS_OK) return
        associate (tip => out%tip, ledger => out%ledger, work => out%hist%work)
            do k = 1, size(d%sim_t_out)
                line = fmt_e(d%sim_t_out(k))//','//fmt_e(tip(1, k))//','//fmt_e(tip(2, k))// &
                       ','//fmt_e(tip(3, k))//','//fmt_e(ledger(3, k))//','// &
                       fmt_e(ledger(1, k))//','//fmt_e(ledger(2, k))
                do i = 1, nwork
                    line = line//','//fmt_e(work(i, k))
                end do
                line = line//','//fmt_e(sum(work(:, k)))//','//fmt_e(ledger(4, k))//','// &
                       fmt_e(out%hist%torque(k))
                call put(unit, ios, line)
            end do
        end associate
        call close_checked(fl, unit, ios, st)
        k = size(d%sim_t_out)
        fl%summary = fmt_int(k)//' output times to '//short(d%sim_t_out(k))//' s ('// &
            trim(merge('rk4     ', 'implicit', d%sim_integrator == 0))//', friction '// &
            trim(FRICTION_LAWS(d%sim_friction + 1))//'); tip w at the end '// &
            fixed(out%tip(2, k), 7)//' m, energy change '// &
            fixed(out%ledger(3, k) - out%ledger(3, 1), 8)//' N m'
    end subroutine run_simulate


    ! ------------------------------------------------------------ estimation

    !> Estimation decks: fit (and compare: the same files), diagnose, improve,
    !! all from the deck's ladder (deck_ladder_start: as beamid.fit,
    !! beamid.diagnose and beamid.improve). `ladder`: its rungs when already
    !! run (beamid.run steps it to show progress): only the files are written.
    subroutine run_estimation(d, fl, st, ladder)
        type(deck_t), intent(in) :: d
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        type(rung_t), intent(in), optional :: ladder(:)
        type(cand_set_t) :: cs
        type(rung_t), allocatable :: rungs(:)
        type(ladder_t) :: lad
        integer :: k, unit, ios

        if (present(ladder)) then
            rungs = ladder
        else
            call deck_ladder_start(d, lad, st)
            do while (.not. lad%done)
                call ladder_step(lad, st)
            end do
            if (st%code == STATUS_OK) rungs = lad%rungs(:lad%n)
        end if
        if (st%code == STATUS_OK) call deck_candidates(d, cs, st)
        if (st%code /= STATUS_OK) return
        associate (fo => rungs(size(rungs))%fit, dg => rungs(size(rungs))%dg)
            fl%summary = d%task//', '//fit_line(d, fo)
            if (d%task == 'improve') then
                fl%summary = ''
                do k = 2, size(rungs)
                    if (len(fl%summary) > 0) fl%summary = fl%summary//', '
                    fl%summary = fl%summary//rungs(k)%effect
                end do
                if (len(fl%summary) == 0) fl%summary = 'none'
                fl%summary = 'improve, effects added: '//fl%summary//'; the last fit '// &
                             fit_line(d, fo)
            end if
            call write_fit_files(d, fo, '', fl, st)
            if (st%code == STATUS_OK .and. (d%task == 'diagnose' .or. d%task == 'improve')) &
                call write_ranking(d, fo, dg, cs, fl, st)
            if (st%code == STATUS_OK .and. d%task == 'compare') &
                call write_compare(d, fo, fl, st)
        end associate
        if (st%code /= STATUS_OK .or. d%task /= 'improve') return
        call open_output(fl, '_ladder.csv', 'step,effect,chi2,dof,chi2_per_dof', unit, &
                         ios, st)
        if (st%code /= STATUS_OK) return
        do k = 1, size(rungs)
            associate (f => rungs(k)%fit)
                call put(unit, ios, fmt_int(k - 1)//','//rungs(k)%effect//','//fmt_e(f%chi2)// &
                         ','//fmt_int(f%dof)//','//fmt_e(chi2_per_dof(f)))
            end associate
        end do
        call close_checked(fl, unit, ios, st)
    end subroutine run_estimation

    !> Task identify: the stages in order (deck_stage_start, as
    !! beamid.identify); `held`: the fits of the first stages when already made
    !! (beamid.run fits them from Python, a stage at a time). Files:
    !! <prefix>_identify.csv (stage, parameter, estimate, sigma before and
    !! after: what each stage taught) and every stage's fit files
    !! <prefix>_<stage>_estimates.csv, _covariance.csv and _residuals.csv.
    subroutine run_identify(d, fl, st, held)
        type(deck_t), intent(in) :: d
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        type(rung_t), intent(in), optional :: held(:)
        type(rung_t), allocatable :: done(:)
        type(deck_t) :: ds
        type(ladder_t) :: lad
        real(dp), allocatable :: known(:), before(:)
        character(len=:), allocatable :: rows
        integer :: k, i, p, unit, ios

        done = [rung_t ::]
        if (present(held)) done = held
        do while (size(done) < size(d%stages))
            call deck_stage_start(d, done, lad, st)
            if (st%code /= STATUS_OK) return
            done = [done, lad%rungs(1)]
        end do
        allocate (known(size(d%params)), source=ieee_value(1.0_dp, ieee_positive_inf))
        known(d%stages(1)%prior_index) = d%stages(1)%prior_sigma
        rows = ''
        do k = 1, size(d%stages)
            associate (f => done(k)%fit)
                before = known(f%free)
                do i = 1, size(f%free)
                    p = f%free(i)
                    rows = rows//d%stages(k)%name//','//param_name(d%nbeams, p)//','// &
                           fmt_e(f%params(p))//','//fmt_e(before(i))//','//fmt_e(f%sigmas(i))// &
                           ','//trim(FLAG_NAMES(min(max(f%flags(i), 0), ubound(FLAG_NAMES, 1))))// &
                           new_line('a')
                    known(p) = f%sigmas(i)
                end do
            end associate
        end do

        fl%summary = 'identify, '//fmt_int(size(d%stages))//' stages ('
        do k = 1, size(d%stages)
            if (k > 1) fl%summary = fl%summary//', '
            fl%summary = fl%summary//d%stages(k)%name
        end do
        fl%summary = fl%summary//'); the last fit '//fit_line(d, done(size(done))%fit)
        call open_output(fl, '_identify.csv', &
                         'stage,parameter,estimate,sigma_before,sigma_after,flag', unit, ios, st)
        if (st%code /= STATUS_OK) return
        if (len(rows) > 0) call put(unit, ios, rows(:len(rows) - 1))
        call close_checked(fl, unit, ios, st)
        do k = 1, size(d%stages)
            if (st%code /= STATUS_OK) return
            call stage_deck(d, d%stages(k), ds)
            call write_fit_files(ds, done(k)%fit, '_'//d%stages(k)%name, fl, st)
        end do
    end subroutine run_identify

    !> Start the next stage of an identify deck, k = size(done) + 1, as a ladder
    !! ended at its fit (beamid_ladder; a weighted fit, as beamid.identify's):
    !! the stage's data and iteration limit, its free parameters and every
    !! earlier stage's (both updated, Eq. 147) from where stage k - 1's fit
    !! (done(k - 1)) ended, with its estimates and full covariance as a priori
    !! information (Eq. 146-148, 164-166; stage 1 from the deck's model with
    !! its a priori values, Eq. 142-145).
    subroutine deck_stage_start(d, done, lad, st)
        type(deck_t), intent(in) :: d
        type(rung_t), intent(in) :: done(:)
        type(ladder_t), intent(out) :: lad
        type(status_t), intent(inout) :: st
        type(deck_t) :: ds
        type(problem_t) :: pb
        integer, allocatable :: free(:)
        integer :: i, k
        k = size(done) + 1
        if (k > size(d%stages)) then
            call set_status(st, ERR_INPUT, 'identify', 'all '//fmt_int(k - 1)//' stages are fitted')
            return
        end if
        call stage_deck(d, d%stages(k), ds)
        pb = deck_problem(ds)
        free = d%stages(k)%free
        if (k == 1) then
            call ladder_start(lad, pb, d%params, free, cand_set_t(), 0.0_dp, 0, st)
        else
            associate (prev => done(k - 1)%fit)
                do i = 1, size(prev%free)
                    if (.not. any(free == prev%free(i))) free = [free, prev%free(i)]
                end do
                call prior_from_covariance(prev%free, prev%estimates, prev%cov, pb%prior, st)
                if (st%code == STATUS_OK) &
                    call ladder_start(lad, pb, prev%params, free, cand_set_t(), 0.0_dp, 0, st)
            end associate
        end if
        call ladder_end_at_fit(lad)
        if (st%code /= STATUS_OK) st%message = "stage '"//d%stages(k)%name//"': "// &
                                               trim(st%message)
        if (st%code /= STATUS_OK .and. allocated(d%exp_names)) call name_experiment(d, st)
    end subroutine deck_stage_start

    !> The deck as its stage's fit deck: the experiments, the stage's data,
    !! rows, free parameters, a priori values and iteration limit (what
    !! deck_problem and write_fit_files read; not a copy of the whole deck,
    !! see beamid_deck copy_measurements).
    subroutine stage_deck(d, stage, ds)
        type(deck_t), intent(in) :: d
        type(stage_t), intent(in) :: stage
        type(deck_t), intent(out) :: ds
        ds%path = d%path
        ds%task = 'fit'
        ds%output = d%output
        ds%nbeams = d%nbeams
        ds%params = d%params
        ds%experiments = d%experiments
        if (allocated(d%exp_kind)) ds%exp_kind = d%exp_kind
        if (allocated(d%exp_specs)) ds%exp_specs = d%exp_specs
        ds%hist = d%hist
        call take_stage(ds, stage)
    end subroutine stage_deck

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
    subroutine write_compare(d, fo, fl, st)
        type(deck_t), intent(in) :: d
        type(fit_result_t), intent(in) :: fo
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
            per_exp(e) = per_exp(e) + fo%normalized(i)**2
        end do
        call residual_structure(level, obs_groups(d%data%obs), fo%normalized, out)
        dof = real(fo%dof, dp)
        p = ieee_value(1.0_dp, ieee_quiet_nan)
        if (fo%dof > 0) p = chi2_sf(fo%chi2 + fo%chi2_prior, fo%dof)
        systematic = (p < 0.01_dp) .or. (out(4) < 0.01_dp) .or. (out(7) < 0.01_dp)
        call open_output(fl, '_compare.csv', 'quantity,value', unit, ios, st)
        if (st%code /= STATUS_OK) return
        call put(unit, ios, 'chi2,'//fmt_e(fo%chi2))
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
        call close_checked(fl, unit, ios, st)
    end subroutine write_compare

    !> (chi2 + chi2_prior) / dof, NaN without degrees of freedom.
    real(dp) function chi2_per_dof(fo)
        type(fit_result_t), intent(in) :: fo
        chi2_per_dof = ieee_value(1.0_dp, ieee_quiet_nan)
        if (fo%dof > 0) chi2_per_dof = (fo%chi2 + fo%chi2_prior)/real(fo%dof, dp)
    end function chi2_per_dof

    !> The deck's estimation problem (beamid_ladder): its experiments, data
    !! rows, a priori information (Eq. 142-145) and iteration limit.
    function deck_problem(d) result(pb)
        type(deck_t), intent(in) :: d
        type(problem_t) :: pb
        type(observation_t), allocatable :: list(:)
        integer :: r
        ! each row its own entry of the observation list, but with the
        ! measurement chain, whose channel masks number the distinct
        ! observations in the core's order (beamid_chain_deck)
        pb = problem_t(nbeams=d%nbeams, row_exp=d%row_exp, row_t=d%data%t, &
                       row_q=[(r, r=1, size(d%data%obs))], obs=d%data%obs, y=d%data%value, &
                       sigma=d%data%sigma, max_iter=d%max_iter, &
                       prior=prior_t(d%prior_index, d%prior_mean, d%prior_sigma))
        call deck_experiments(d, pb%exp_kind, pb%specs)
        pb%hist = d%hist
        if (.not. chain_asked(pb%specs) .and. .not. asks_noise(d)) return
        list = ordered_observations(d%data%obs)
        pb%obs = list
        pb%row_q = [(findloc(same_observation(list, d%data%obs(r)), .true., 1), &
                     r=1, size(d%data%obs))]
    end function deck_problem

    !> Is noise larger than stated among the deck's candidates (its rung
    !! estimates every channel's sigma: channel masks over distinct observations)?
    pure logical function asks_noise(d)
        type(deck_t), intent(in) :: d
        integer :: c
        asks_noise = .false.
        if (.not. allocated(d%candidates)) return
        do c = 1, size(d%candidates)
            if (trim(adjustl(d%candidates(c))) == 'noise') asks_noise = .true.
        end do
    end function asks_noise

    !> The name of parameter k of the deck's fit: the model's, then the
    !! measurement chain's nuisance parameters (t0[experiment],
    !! bias[experiment:quantity], scale[...], chain_layout's order).
    function deck_param_name(d, k) result(name)
        type(deck_t), intent(in) :: d
        integer, intent(in) :: k
        character(len=:), allocatable :: name
        type(problem_t) :: pb
        integer, allocatable :: kinds(:), exps(:), qs(:)
        type(status_t) :: st
        integer :: j
        if (k <= param_count(d%nbeams)) then
            name = param_name(d%nbeams, k)
            return
        end if
        pb = deck_problem(d)
        call chain_layout(pb%exp_kind, pb%specs, kinds, exps, qs, st, size(pb%obs))
        j = k - param_count(d%nbeams)
        name = '#'//fmt_int(k)
        if (st%code /= STATUS_OK .or. j > size(kinds)) return
        select case (kinds(j))
        case (NU_T0)
            name = 't0['//trim(d%exp_names(exps(j)))//']'
        case (NU_V0)
            name = 'v0['//trim(d%exp_names(exps(j)))//']'
        case (NU_BIAS)
            name = 'bias['//trim(d%exp_names(exps(j)))//':'//obs_label(pb%obs(qs(j)))//']'
        case default
            name = 'scale['//trim(d%exp_names(exps(j)))//':'//obs_label(pb%obs(qs(j)))//']'
        end select
    end function deck_param_name

    !> The deck's start: its model's parameters, then the nuisance
    !! parameters of its measurement chain at their null values (t0 = 0,
    !! b = 0, s = 1), and the free ones: the deck's, then every nuisance
    !! parameter.
    subroutine deck_start(d, params, free, st)
        type(deck_t), intent(in) :: d
        real(dp), allocatable, intent(out) :: params(:)
        integer, allocatable, intent(out) :: free(:)
        type(status_t), intent(inout) :: st
        type(problem_t) :: pb
        integer, allocatable :: kinds(:), exps(:), qs(:)
        integer :: j, np
        params = d%params
        free = d%free
        if (.not. allocated(d%exp_specs)) return
        if (.not. chain_asked(d%exp_specs)) return
        pb = deck_problem(d)
        call chain_layout(pb%exp_kind, pb%specs, kinds, exps, qs, st, size(pb%obs))
        if (st%code /= STATUS_OK) return
        np = size(params)
        params = [params, merge(1.0_dp, 0.0_dp, kinds == NU_SCALE)]
        free = [free, (np + j, j=1, size(kinds))]
    end subroutine deck_start

    !> The deck's experiments as beamid_inverse takes them: kinds and specs.
    pure subroutine deck_experiments(d, kinds, specs)
        type(deck_t), intent(in) :: d
        integer, allocatable, intent(out) :: kinds(:)
        type(experiment_spec_t), allocatable, intent(out) :: specs(:)
        integer :: e
        allocate (specs(size(d%experiments)), kinds(size(d%experiments)))
        do e = 1, size(d%experiments)
            kinds(e) = d%experiments(e)%kind
            call specs(e)%set(EV_FX, d%experiments(e)%fx)
            call specs(e)%set(EV_FY, d%experiments(e)%fy)
            call specs(e)%set(EV_MOMENT, d%experiments(e)%moment)
            call specs(e)%set(EV_WIRE_LENGTH, d%experiments(e)%wire_length)
        end do
        if (allocated(d%exp_kind)) then
            where (d%exp_kind > 0) kinds = d%exp_kind
            do e = 1, size(d%experiments)
                if (d%exp_kind(e) > 0) specs(e) = d%exp_specs(e)
                ! the measurement chain's keys of a static experiment too
                if (d%exp_kind(e) == 0) call specs(e)%take_chain(d%exp_specs(e))
            end do
        end if
    end subroutine deck_experiments

    !> The deck's experiments as named specs, the form the fronts take
    !! (beamid_api_deck api_deck_handle_specs): their kinds, and for each
    !! experiment e every key k of the core's key table (beamid_family
    !! SPEC_KEYS, in its order) with its value, as triples kv_exp(i) = e,
    !! kv_key(i) = k, kv_value(i): no positional layout leaves the core.
    pure subroutine deck_specs(d, kinds, kv_exp, kv_key, kv_value)
        type(deck_t), intent(in) :: d
        integer, allocatable, intent(out) :: kinds(:), kv_exp(:), kv_key(:)
        real(dp), allocatable, intent(out) :: kv_value(:)
        type(experiment_spec_t), allocatable :: specs(:)
        integer :: e, k, nk
        if (.not. allocated(d%experiments)) then   ! a deck without experiments
            allocate (kinds(0), kv_exp(0), kv_key(0), kv_value(0))
            return
        end if
        call deck_experiments(d, kinds, specs)
        nk = size(SPEC_KEYS)
        kv_exp = [((e, k = 1, nk), e = 1, size(kinds))]
        kv_key = [((k, k = 1, nk), e = 1, size(kinds))]
        kv_value = [((specs(e)%get(k), k = 1, nk), e = 1, size(kinds))]
    end subroutine deck_specs

    !> The deck's candidates: every effect named, with its parameters; in a
    !! deck with releases or modal tests `mesh` is the mesh test of beamid_dyn_diagnosis
    !! (as beamid.diagnose does), not a candidate without parameters.
    subroutine deck_candidates(d, cs, st)
        type(deck_t), intent(in) :: d
        type(cand_set_t), intent(out) :: cs
        type(status_t), intent(inout) :: st
        integer :: c
        logical :: dyn
        type(candidate_t) :: one
        dyn = .false.
        ! experiments with a mesh of their own (releases, modal tests)
        if (allocated(d%exp_kind)) dyn = has_mesh(d%exp_kind)
        allocate (cs%names(0), cs%cands(0))
        do c = 1, size(d%candidates)
            if (dyn .and. trim(adjustl(d%candidates(c))) == 'mesh') then
                cs%with_mesh = .true.
                cycle
            end if
            ! the measurement chain's row candidates of the ladder (row_rung)
            if (trim(adjustl(d%candidates(c))) == 'gross_errors') then
                cs%gross = .true.
                cycle
            end if
            if (trim(adjustl(d%candidates(c))) == 'noise') then
                cs%noise = .true.
                cycle
            end if
            one%name = trim(d%candidates(c))
            call effect_params(d%nbeams, d%candidates(c), one%params, st)
            if (st%code /= STATUS_OK) return
            cs%names = [character(len=32) :: cs%names, d%candidates(c)]
            cs%cands = [cs%cands, one]
        end do
    end subroutine deck_candidates

    !> Start the ladder (beamid_ladder) of an estimation deck's task on the
    !! deck's problem and candidates: the fit of its free parameters, then
    !! (ladder_step) for diagnose the fit's diagnosis, for improve up to one
    !! rung per candidate; a fit or compare deck's ladder ends at its fit,
    !! undiagnosed. run_estimation steps it to the end; beamid.run steps it
    !! from Python (its progress shown) and has the files written from it.
    subroutine deck_ladder_start(d, lad, st)
        type(deck_t), intent(in) :: d
        type(ladder_t), intent(out) :: lad
        type(status_t), intent(inout) :: st
        type(cand_set_t) :: cs
        real(dp), allocatable :: params(:)
        integer, allocatable :: free(:)
        call deck_candidates(d, cs, st)
        if (st%code == STATUS_OK) call deck_start(d, params, free, st)
        if (st%code == STATUS_OK) call ladder_start(lad, deck_problem(d), params, free, cs, &
            d%alpha, merge(size(d%candidates), 0, d%task == 'improve'), st)
        if (d%task == 'fit' .or. d%task == 'compare') call ladder_end_at_fit(lad)
        if (st%code /= STATUS_OK .and. allocated(d%exp_names)) call name_experiment(d, st)
    end subroutine deck_ladder_start

    !> <prefix><part>_estimates.csv, _covariance.csv and _residuals.csv.
    subroutine write_fit_files(d, fo, part, fl, st)
        type(deck_t), intent(in) :: d
        type(fit_result_t), intent(in) :: fo
        character(len=*), intent(in) :: part
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        character(len=:), allocatable :: line
        integer :: unit, ios, i, j, r

        if (size(fo%predictions) /= size(d%row_exp)) then   ! a fit of another deck's rows
            call set_status(st, ERR_INPUT, 'fit', 'predictions of '// &
                            fmt_int(size(fo%predictions))//' rows, expected '// &
                            fmt_int(size(d%row_exp))//' (the data rows of '//d%path//')')
            return
        end if
        call open_output(fl, part//'_estimates.csv', 'name,estimate,sigma,flag', unit, ios, st)
        if (st%code /= STATUS_OK) return
        do i = 1, size(fo%free)
            call put(unit, ios, deck_param_name(d, fo%free(i))//','// &
                     fmt_e(fo%params(fo%free(i)))//','//fmt_e(fo%sigmas(i))//','// &
                     trim(FLAG_NAMES(min(max(fo%flags(i), 0), ubound(FLAG_NAMES, 1)))))
        end do
        call put(unit, ios, 'chi2,'//fmt_e(fo%chi2)//',,')
        call put(unit, ios, 'chi2_prior,'//fmt_e(fo%chi2_prior)//',,')
        call put(unit, ios, 'dof,'//fmt_int(fo%dof)//',,')
        call put(unit, ios, 'iterations,'//fmt_int(fo%iterations)//',,')
        call put(unit, ios, 'condition_number,'//fmt_e(fo%cond)//',,')
        call close_checked(fl, unit, ios, st)
        if (st%code /= STATUS_OK) return

        line = 'name'
        do i = 1, size(fo%free)
            line = line//','//deck_param_name(d, fo%free(i))
        end do
        call open_output(fl, part//'_covariance.csv', line, unit, ios, st)
        if (st%code /= STATUS_OK) return
        do i = 1, size(fo%free)
            line = deck_param_name(d, fo%free(i))
            do j = 1, size(fo%free)
                line = line//','//fmt_e(fo%cov(i, j))
            end do
            call put(unit, ios, line)
        end do
        call close_checked(fl, unit, ios, st)
        if (st%code /= STATUS_OK) return

        ! a fit with the chain's row treatments (beamid_chain_fit): the sigma each
        ! row was judged with (estimated where asked), its last weight (0: a
        ! burn-in row) and 1 for a gross error
        line = ''
        if (allocated(fo%row_sigma)) line = ',weight,gross_error'
        call open_output(fl, part//'_residuals.csv', &
                         'experiment,t,quantity,measured,model,sigma,normalized'//line, unit, &
                         ios, st)
        if (st%code /= STATUS_OK) return
        do r = 1, size(d%row_exp)
            if (allocated(fo%row_sigma)) then
                call put(unit, ios, trim(d%data%experiment(r))//','//fmt_g(d%data%t(r))//','// &
                         obs_label(d%data%obs(r))//','//fmt_e(d%data%value(r))//','// &
                         fmt_e(fo%predictions(r))//','//fmt_e(fo%row_sigma(r))//','// &
                         fmt_e(fo%normalized(r))//','//fmt_e(fo%row_weight(r))//','// &
                         trim(merge('1', '0', fo%row_gross(r))))
                cycle
            end if
            call put(unit, ios, trim(d%data%experiment(r))//','//fmt_g(d%data%t(r))//','// &
                     obs_label(d%data%obs(r))//','//fmt_e(d%data%value(r))//','// &
                     fmt_e(fo%predictions(r))//','//fmt_e(d%data%sigma(r))//','// &
                     fmt_e(fo%normalized(r)))
        end do
        call close_checked(fl, unit, ios, st)
    end subroutine write_fit_files

    !> <prefix>_ranking.csv: candidates best first, one row per parameter
    !! (columns as beamid.fit_decks.write_ranking). The drop, p-value,
    !! estimate and sigma are the refit's when one was made, else the score
    !! test's (first order).
    subroutine write_ranking(d, fo, dg, cs, fl, st)
        type(deck_t), intent(in) :: d
        type(fit_result_t), intent(in) :: fo
        type(diag_out_t), intent(in) :: dg
        type(cand_set_t), intent(in) :: cs
        type(files_t), intent(inout) :: fl
        type(status_t), intent(inout) :: st
        real(dp) :: nan, score_drop, score_p, lr_drop, lr_p, drop, p, est, sig
        logical :: tested, refit
        integer :: unit, ios, rank, c, j, k, nj, state, u, q, at_mesh, ntested
        integer, allocatable :: block(:)
        character(len=:), allocatable :: pname, flags

        nan = ieee_value(1.0_dp, ieee_quiet_nan)
        call open_output(fl, '_ranking.csv', 'rank,effect,state,parameter,score_drop,'// &
                         'score_p,refit_drop,refit_p,chi2_drop,p_value,estimate,sigma,'// &
                         'physical,identifiable,significant,acceptable,rival', unit, ios, st)
        if (st%code /= STATUS_OK) return
        ! the mesh test ranks first when significant, else after the tested
        ! candidates (beamid.dyn_diagnosis.diagnose_dynamic)
        at_mesh = 0
        if (dg%mesh%done) then
            ntested = count(dg%diag%cand%state == 0)
            at_mesh = merge(1, ntested + 1, dg%mesh%significant)
        end if
        rank = 0
        do q = 1, size(dg%diag%ranking) + merge(1, 0, at_mesh > 0)
            rank = rank + 1
            if (rank == at_mesh) then
                call put(unit, ios, fmt_int(rank)//',mesh,'//trim(CAND_NAMES(0))//',,'// &
                         fmt_e(dg%mesh%drop)//','//fmt_e(dg%mesh%p_value)//','// &
                         fmt_e(dg%mesh%drop)//','//fmt_e(dg%mesh%p_value)//','// &
                         fmt_e(dg%mesh%drop)//','//fmt_e(dg%mesh%p_value)//','// &
                         fmt_e(nan)//','//fmt_e(nan)//',1,1,'//b2s(dg%mesh%significant)// &
                         ','//b2s(dg%mesh%significant)//',0')
                cycle
            end if
            c = dg%diag%ranking(q - merge(1, 0, at_mesh > 0 .and. q > at_mesh))
            associate (cr => dg%diag%cand(c))
                state = cr%state
                tested = state == 0
                refit = tested .and. cr%refit_done .and. cr%refit_ok
                score_drop = merge(cr%score%drop, nan, tested)
                score_p = merge(cr%score%p_value, nan, tested)
                lr_drop = merge(cr%lr_drop, nan, refit)
                lr_p = merge(cr%lr_p, nan, refit)
                drop = score_drop
                p = score_p
                if (refit .and. .not. ieee_is_nan(lr_drop)) drop = lr_drop
                if (refit .and. .not. ieee_is_nan(lr_p)) p = lr_p
                if (tested) then
                    flags = b2s(cr%score%physical)//','//b2s(cr%score%identifiable)//','// &
                            b2s(cr%significant)//','//b2s(cr%acceptable)//','//b2s(cr%rival)
                else
                    flags = '1,1,0,0,0'
                end if
                ! the block as tested (a dynamic block reduced to the members
                ! the data determine; the others are left at their null values)
                block = cs%cands(c)%params
                if (dg%dynamic .and. tested) block = dg%used(c)%params
                nj = size(block)
                do j = 1, max(nj, 1)
                    pname = ''
                    est = nan
                    sig = nan
                    if (nj > 0) then
                        k = block(j)
                        u = j
                        pname = param_name(d%nbeams, k)
                        if (refit) then
                            est = cr%refit%params(k)
                            sig = cr%refit%sigmas(size(fo%free) + u)
                        else if (tested .and. allocated(cr%score%estimate)) then
                            est = fo%params(k) + cr%score%estimate(u)
                            sig = cr%score%sigma(u)
                        else if (tested) then
                            est = fo%params(k)
                            sig = 0.0_dp
                        end if
                    end if
                    call put(unit, ios, fmt_int(rank)//','//trim(cs%names(c))//','// &
                             trim(CAND_NAMES(state))//','//pname//','//fmt_e(score_drop)//','// &
                             fmt_e(score_p)//','//fmt_e(lr_drop)//','//fmt_e(lr_p)//','// &
                             fmt_e(drop)//','//fmt_e(p)//','//fmt_e(est)//','//fmt_e(sig)//','// &
                             flags)
                end do
            end associate
        end do
        call close_checked(fl, unit, ios, st)
    end subroutine write_ranking

    !> <prefix><suffix>: 'quantity,value' rows (names, values), then the solver's Newton
    !! iterations and load steps (counts).
    subroutine write_summary(fl, suffix, names, values, counts, st)
        type(files_t), intent(inout) :: fl
        character(len=*), intent(in) :: suffix, names(:)
        real(dp), intent(in) :: values(:)
        integer, intent(in) :: counts(2)
        type(status_t), intent(inout) :: st
        integer :: unit, ios, i
        call open_output(fl, suffix, 'quantity,value', unit, ios, st)
        if (st%code /= STATUS_OK) return
        do i = 1, size(values)
            if (ios == 0) write (unit, '(a,",",es24.16e3)', iostat=ios) trim(names(i)), values(i)
        end do
        if (ios == 0) write (unit, '(a,",",i0)', iostat=ios) 'newton_iterations', counts(1)
        if (ios == 0) write (unit, '(a,",",i0)', iostat=ios) 'load_steps', counts(2)
        call close_checked(fl, unit, ios, st)
    end subroutine write_summary

    !> <prefix><suffix>: the header, then one row per column of `table`.
    subroutine write_table(fl, suffix, header, table, st)
        type(files_t), intent(inout) :: fl
        character(len=*), intent(in) :: suffix, header
        real(dp), intent(in) :: table(:, :)
        type(status_t), intent(inout) :: st
        integer :: unit, ios, i
        call open_output(fl, suffix, header, unit, ios, st)
        if (st%code /= STATUS_OK) return
        do i = 1, size(table, 2)
            if (ios == 0) write (unit, '(*(es24.16e3,:,","))', iostat=ios) table(:, i)
        end do
        call close_checked(fl, unit, ios, st)
    end subroutine write_table

    !> A logical as '0' or '1'.
    pure function b2s(x) result(text)
        logical, intent(in) :: x
        character(len=1) :: text
        text = merge('1', '0', x)
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

    !> Open output file <prefix><suffix> under its temporary name (its folder
    !! made first) and write its header line.
    subroutine open_output(fl, suffix, header, unit, ios, st)
        type(files_t), intent(inout) :: fl
        character(len=*), intent(in) :: suffix, header
        integer, intent(out) :: unit, ios
        type(status_t), intent(inout) :: st
        character(len=512) :: msg
        if (.not. fl%folder_ok) call make_folder(fl%prefix, st)
        fl%folder_ok = st%code == STATUS_OK
        if (.not. fl%folder_ok) return
        fl%last = fl%prefix//suffix
        open (newunit=unit, file=fl%last//TMP_SUFFIX, status='replace', action='write', &
              iostat=ios, iomsg=msg)
        if (ios /= 0) then
            call set_status(st, ERR_OUTPUT, 'output', 'cannot write '//fl%last//': '//trim(msg))
            return
        end if
        fl%names = fl%names//fl%last//new_line('a')
        write (unit, '(a)', iostat=ios) header
    end subroutine open_output

    !> Close the file opened last; a failed write is an error naming the file.
    subroutine close_checked(fl, unit, ios, st)
        type(files_t), intent(in) :: fl
        integer, intent(in) :: unit, ios
        type(status_t), intent(inout) :: st
        integer :: ios_close
        close (unit, iostat=ios_close)
        if (ios /= 0 .or. ios_close /= 0) call set_status(st, ERR_OUTPUT, 'output', &
            'writing '//fl%last//' failed (disk full or no permission)')
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
