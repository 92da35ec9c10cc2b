!> Namelist input decks (format: docs/decks.md), the one reader of both
!! fronts: beamid-batch and Python (beamid_api_deck) call read_deck.
!!
!! A deck holds the groups &beamid (task, output, preset, nbeams), &model
!! (per-beam and per-mass-point arrays and the effect parameters), &load,
!! &static and &fe; estimation decks (tasks fit, compare, diagnose, improve)
!! &beamid, &model, one &experiment per experiment and &fit, whose data CSV
!! is read and validated here too (beamid_measurements); dynamic decks (task
!! simulate) &beamid, &model, &load (the tip load held before the release)
!! and &simulate; any deck &published. The file is split into groups and
!! items by beamid_namelist, then every group is checked and every problem
!! collected (deck_t%errors, one per line, naming the file, line, group,
!! variable, value and what was expected): a value of the wrong type, NaN or
!! Infinity, too many values, a group cut short, unknown or repeated names,
!! values out of range, nonphysical parameters, and sizes beyond the memory
!! bound (MAX_BYTES) before anything is allocated. Nothing defaults silently.
module beamid_deck
    use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_nan
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_DECK, ERR_INPUT, STATUS_OK, fmt_int, &
                             fmt_real, lower, fmt_bytes, MAX_BYTES
    use beamid_model, only: param_count, param_name, param_index_beam, param_index_mass, &
                            param_index_joint_flex, param_index_global, chain_t, &
                            param_index_thickness, PACE_THICKNESS, chain_from_vector, &
                            IB_L, IB_EI, IB_EA, IB_RHO, IB_C, IM_M, IM_J, &
                            IM_MU, IM_C, IG_AXIAL_COUPLING, IG_ROOT_FLEX, IG_ETA, IG_R_MOTOR, &
                            IG_TAU_MOTOR
    use beamid_presets, only: preset_params
    use beamid_observations, only: observation_t, parse_observation
    use beamid_arclength, only: static_load_t, LOAD_TIP, LOAD_WIRE
    use beamid_effects, only: effect_params, default_effects, known_effects, FAMILY_STATIC, &
                              FAMILY_MODAL
    use beamid_chain_deck, only: CHAIN_KEYS, set_chain_key, chain_sigma_missing
    use beamid_inverse, only: experiment_spec_t, EXP_RELEASE, EV_FX, EV_FY, EV_MOMENT, &
                              EV_NEPB, EV_GAIN, EV_WIRE_LENGTH, EV_METHOD, EV_LAW, EV_RTOL, EV_DT
    use beamid_dynamic_experiments, only: exp_histories_t
    use beamid_deck_history, only: read_history_groups
    use beamid_family, only: EXP_MODAL
    use beamid_measurements, only: measurements_t, read_measurements, check_static_rows, fmt_g, &
                                   read_channel_file, sensor_t
    use beamid_namelist, only: nml_merge_items, nml_file_t, nml_group_t, nml_text_t, &
                               nml_read_file, nml_count, &
                               nml_find, nml_check_keys, nml_real, nml_reals, nml_int, nml_str, &
                               nml_strs, nml_logical, nml_given, add_error, nml_ints
    implicit none
    private

    public :: deck_t, read_deck, param_lookup, KNOWN_GROUPS, deck_set_task, take_stage
    public :: FRICTION_LAWS

    integer, parameter :: NAME_LEN = 32
    character(len=*), parameter :: KNOWN_GROUPS = &
        ' beamid model load static fe published experiment fit simulate sensor history '
    !> Tasks the batch runs.
    character(len=*), parameter :: KNOWN_TASKS = &
        ' static fe_static fe_modes fit compare diagnose improve simulate identify '
    !> Estimation tasks and the groups their decks may hold.
    character(len=*), parameter :: FIT_TASKS = ' fit compare diagnose improve identify '
    character(len=*), parameter :: FIT_GROUPS = ' beamid model experiment fit published sensor '// &
                                                'history '
    !> Size bounds, checked before anything is allocated: beams of a chain,
    !! output times, and the memory a mesh or a table may need (bytes).
    integer, parameter :: MAX_BEAMS = 1000
    integer, parameter :: MAX_TIMES = 10000000
    !> Groups that may appear more than once.
    character(len=*), parameter :: REPEATABLE = ' experiment published sensor history '
    !> The classes of a documented deviation (&published kind), '' for none.
    character(len=*), parameter :: DEVIATION_KINDS = '||formulation|random draws|unexplained|'
    !> The words of integrator and friction (codes: read_choice's callers).
    character(len=*), parameter :: INTEGRATORS(2) = [character(len=8) :: 'implicit', 'rk4']
    character(len=*), parameter :: FRICTION_LAWS(3) = [character(len=12) :: 'sign', 'smooth', &
                                                       'sign_literal']

    !> One stage of an identification deck (task identify: one &fit group
    !! per stage, in order; beamid_tasks carries each stage's estimates and
    !! covariance into the next as a priori information, Eq. 146-148, 164-166).
    type, public :: stage_t
        character(len=:), allocatable :: name
        character(len=:), allocatable :: data_path
        !> the data file is a logger's wide CSV of this experiment (read
        !! through the deck's &sensor table; '' for the long format) and the
        !! sigma of its channels without one of their own (0: none)
        character(len=:), allocatable :: logger_experiment
        real(dp) :: logger_sigma = 0.0_dp
        type(measurements_t) :: data
        integer, allocatable :: row_exp(:)              !< experiment index of each data row
        integer, allocatable :: free(:)
        integer, allocatable :: prior_index(:)          !< a priori (first stage only)
        real(dp), allocatable :: prior_mean(:), prior_sigma(:)
        integer :: max_iter = 50
    end type stage_t

    !> Everything a deck says.
    type :: deck_t
        character(len=:), allocatable :: path
        !> Every problem found, one per line (empty when the deck is valid);
        !! the status holds the first one.
        character(len=:), allocatable :: errors
        !> The model was read without errors (checks that need it run then).
        logical :: model_ok = .false.
        !> The &published groups, one line per item (tab separated): 'P table
        !! row note' opens a group, then 'K kind section' when the group has a
        !! kind, 'Q quantity value digits' per value and 'D name' per
        !! documented deviation (read by beamid reproduce).
        character(len=:), allocatable :: published
        character(len=:), allocatable :: task       !< 'static'
        character(len=:), allocatable :: output     !< output prefix, relative to the deck
        integer :: nbeams = 0
        real(dp), allocatable :: params(:)
        type(static_load_t) :: load
        integer, allocatable :: wrt(:)              !< parameter indices for sensitivities
        integer :: shape_points = 101
        real(dp) :: tol = 0.0_dp                    !< 0: solver default
        logical :: has_load = .false.
        ! &fe (tasks fe_static, fe_modes; docs/fe.md)
        integer :: fe_elements_per_beam = 4
        integer :: fe_moment_form = 0               !< 0: Eq. 78, 1: exact
        logical :: fe_rotary_inertia = .false.
        logical :: fe_point_masses = .true.
        integer :: fe_steps = 0
        real(dp) :: fe_tol = 0.0_dp
        ! &experiment and &fit (tasks fit, compare, diagnose, improve; docs/decks.md)
        character(len=:), allocatable :: exp_names(:)   !< experiment names, deck order
        type(static_load_t), allocatable :: experiments(:)
        !> release experiments (kind = 'release', issue 13): exp_kind(e) = 3
        !! and exp_specs(e) their spec (beamid_family experiment_spec_t); 0
        !! for the static experiments (their load is experiments(e); their
        !! spec holds the measurement chain's keys only)
        integer, allocatable :: exp_kind(:)
        type(experiment_spec_t), allocatable :: exp_specs(:)
        character(len=:), allocatable :: data_path      !< measurement CSV
        !> the &sensor table: channel names of a logger file, their
        !! observations and sigmas (0: none of its own)
        type(sensor_t), allocatable :: sensors(:)
        !> for the Python reader: 'N name observation sigma' per sensor and
        !! 'C stage experiment sigma' per &fit reading a logger file (tab
        !! separated)
        character(len=:), allocatable :: channel_text
        type(measurements_t) :: data
        integer, allocatable :: row_exp(:)              !< experiment index of each data row
        integer, allocatable :: free(:)                 !< parameter indices to estimate
        integer, allocatable :: prior_index(:)          !< a priori (Eq. 142-145)
        real(dp), allocatable :: prior_mean(:), prior_sigma(:)
        character(len=NAME_LEN), allocatable :: candidates(:) !< effects for diagnose/improve
        real(dp) :: alpha = 0.01_dp
        integer :: max_iter = 50
        !> task identify: the stages (the deck's own fit fields hold the first)
        type(stage_t), allocatable :: stages(:)
        !> the stages for the Python reader, one line each (read_fit_groups)
        character(len=:), allocatable :: stage_text
        ! &simulate (task simulate; docs/decks.md, Dynamic decks): the arguments of
        ! beamid.simulate, defaults resolved as there
        real(dp), allocatable :: sim_t_out(:)           !< output times (s)
        integer :: sim_elements_per_beam = 4
        integer :: sim_integrator = 1                   !< 0 rk4, 1 implicit
        integer :: sim_friction = 0                     !< 0 sign, 1 smooth, 2 sign_literal
        real(dp) :: sim_dt = 0.0_dp                     !< 0: default (1e-5 s)
        real(dp) :: sim_rtol = 0.0_dp                   !< 0: default (1e-9, in m)
        real(dp) :: sim_atol = 0.0_dp                   !< 0: rtol
        real(dp) :: sim_motor_gain = 0.0_dp
        real(dp) :: sim_friction_velocity = 1.0e-4_dp   !< smooth law's vs (m/s)
        !> &history groups (issue 28): the load histories of the release
        !! experiments (a simulate deck's: experiment 1)
        type(exp_histories_t) :: hist
    end type deck_t

contains

    !> Index of the named parameter (0 when unknown). Joint 1 may also be
    !! called joint1 (m_joint1 = m_elbow).
    pure integer function param_lookup(nbeams, name)
        integer, intent(in) :: nbeams
        character(len=*), intent(in) :: name
        integer :: i
        character(len=:), allocatable :: key
        key = trim(adjustl(name))
        if (nbeams >= 2) then
            i = index(key, 'joint1')
            if (i > 0 .and. len(key) == i + 5) key = key(:i - 1)//'elbow'
            if (key == 'joint1_flex') key = 'elbow_flex'
        end if
        param_lookup = 0
        do i = 1, param_count(nbeams)
            if (param_name(nbeams, i) == key) then
                param_lookup = i
                return
            end if
        end do
    end function param_lookup

    !> Read and validate a deck: every problem is collected (deck%errors, one
    !! per line, each naming the file, the line, the group, the variable, the
    !! value and what was expected); the status holds the first one and the
    !! count. A file that cannot be read is ERR_IO, a bad deck ERR_DECK.
    subroutine read_deck(path, deck, stat, fit_keys)
        character(len=*), intent(in) :: path
        type(deck_t), intent(out) :: deck
        type(status_t), intent(inout) :: stat
        !> items of &fit given apart (the command line's measurement chain
        !! options of beamid fit/diagnose/improve): they replace the deck's
        character(len=*), intent(in), optional :: fit_keys
        type(nml_file_t) :: f
        character(len=:), allocatable :: errors

        deck%path = path
        deck%errors = ''
        errors = ''
        call nml_read_file(path, f, errors, stat)
        if (stat%code /= STATUS_OK) return
        if (present(fit_keys)) call nml_merge_items(f, 'fit', fit_keys, 'command line', errors)
        ! a CSV given as a deck (no group, one error said) is said in one line
        if (size(f%groups) > 0 .or. index(errors, ': a measurement CSV file (') == 0) &
            call read_all(f, deck, errors)
        if (len(errors) > 0) then
            deck%errors = errors(:len(errors) - 1)
            call set_status(stat, ERR_DECK, 'deck', first_line(errors))
            stat%message = first_line(errors)
            if (count_lines(errors) > 1) stat%message = trim(stat%message)//' (and '// &
                fmt_int(count_lines(errors) - 1)//' more problems)'
        end if
    end subroutine read_deck

    pure function first_line(text) result(line)
        character(len=*), intent(in) :: text
        character(len=:), allocatable :: line
        integer :: k
        k = index(text, new_line('a'))
        if (k == 0) k = len(text) + 1
        line = text(:k - 1)
    end function first_line

    pure integer function count_lines(text)
        character(len=*), intent(in) :: text
        integer :: k
        count_lines = 0
        do k = 1, len(text)
            if (text(k:k) == new_line('a')) count_lines = count_lines + 1
        end do
    end function count_lines

    !> The groups of the deck in turn; stops early only when a later group
    !! cannot be read without an earlier value (the number of beams).
    subroutine read_all(f, deck, errors)
        type(nml_file_t), intent(in) :: f
        type(deck_t), intent(inout) :: deck
        character(len=:), allocatable, intent(inout) :: errors
        character(len=:), allocatable :: task, output, preset, name
        integer :: k, nbeams, nb_preset, ib
        real(dp) :: t_last
        logical :: given, is_fit, ok_head, out_ok
        real(dp), allocatable :: base(:)
        type(status_t) :: st

        ! ---- group names
        do k = 1, size(f%groups)
            name = f%groups(k)%name
            if (index(KNOWN_GROUPS, ' '//name//' ') == 0) then
                call add_error(errors, f%path//', line '//fmt_int(f%groups(k)%line)// &
                               ': unknown group &'//name//', expected one of:'// &
                               KNOWN_GROUPS(:len_trim(KNOWN_GROUPS)))
            else if (index(REPEATABLE, ' '//name//' ') == 0 .and. nml_find(f, name) /= k .and. &
                     name /= 'fit') then   ! &fit: once, or per stage (read_fit_groups)
                call add_error(errors, f%path//', line '//fmt_int(f%groups(k)%line)// &
                               ': group &'//name//' appears '//fmt_int(nml_count(f, name))// &
                               ' times (once only)')
            end if
        end do
        deck%published = ''
        do k = 1, size(f%groups)
            if (f%groups(k)%name == 'published') call read_published(f, f%groups(k), &
                                                                     deck%published, errors)
        end do

        ! ---- &beamid
        ib = nml_find(f, 'beamid')
        if (ib == 0) then
            call add_error(errors, f%path//': group &beamid is missing (task, output, preset)')
            return
        end if
        associate (g => f%groups(ib))
            call nml_check_keys(f, g, ' task output preset nbeams ', errors)
            task = 'static'
            output = ''
            preset = ''
            nbeams = 0
            call nml_str(f, g, 'task', task, given, errors)
            call nml_str(f, g, 'output', output, out_ok, errors)
            call nml_str(f, g, 'preset', preset, given, errors)
            call nml_int(f, g, 'nbeams', nbeams, given, errors)
            task = lower(trim(adjustl(task)))
            if (index(KNOWN_TASKS, ' '//task//' ') == 0 .or. len(task) == 0) then
                call add_error(errors, f%path//', line '//fmt_int(g%line)//": &beamid task = '"// &
                               task//"', expected one of:"//KNOWN_TASKS(:len_trim(KNOWN_TASKS)))
                return
            end if
            if (len_trim(output) == 0 .and. (out_ok .or. .not. nml_given(g, 'output'))) &
                call add_error(errors, &
                f%path//', line '// &
                fmt_int(g%line)//': &beamid output is missing: give the output path prefix')
            if (len(output) > 4000) call add_error(errors, f%path//': &beamid output is '// &
                fmt_int(len(output))//' characters long, expected at most 4000')
            is_fit = index(FIT_TASKS, ' '//task//' ') > 0
            call check_task_groups(f, task, is_fit, errors)
            ! estimation decks start from the PACE arm unless they name another preset
            if (is_fit .and. len_trim(preset) == 0) preset = 'pace'
            ok_head = .true.
            if (len_trim(preset) > 0) then
                call preset_params(trim(preset), nb_preset, base, st)
                if (st%code /= STATUS_OK) then
                    call add_error(errors, f%path//', line '//fmt_int(g%line)// &
                                   ": &beamid preset = '"//trim(preset)// &
                                   "', expected 'pace' or 'cantilever'")
                    return
                end if
                if (nbeams == 0) nbeams = nb_preset
                if (nbeams /= nb_preset) then
                    call add_error(errors, f%path//', line '//fmt_int(g%line)// &
                                   ': &beamid nbeams = '//fmt_int(nbeams)//" but preset '"// &
                                   trim(preset)//"' has "//fmt_int(nb_preset)//' beams')
                    return
                end if
            else if (nbeams < 1 .or. nbeams > MAX_BEAMS) then
                call add_error(errors, f%path//', line '//fmt_int(g%line)// &
                               ': &beamid nbeams = '//fmt_int(nbeams)//', expected 1 to '// &
                               fmt_int(MAX_BEAMS)//" (or a preset, 'pace' or 'cantilever')")
                return
            else
                base = structure_base(nbeams)
            end if
        end associate
        deck%nbeams = nbeams
        deck%task = task
        deck%output = trim(output)

        call read_model(f, nbeams, base, len_trim(preset) > 0, deck, errors)
        if (is_fit) then
            call read_fit_groups(f, deck, errors)
            call fit_histories()
            return
        end if
        call read_load(f, deck, errors)
        if (task == 'simulate') then
            call read_simulate_group(f, deck, errors)
            t_last = -1.0_dp
            if (allocated(deck%sim_t_out)) then
                if (size(deck%sim_t_out) > 0) t_last = maxval(deck%sim_t_out)
            end if
            call read_history_groups(f, [character(len=1) ::], [logical ::], [t_last], &
                                     deck%hist, errors)
            return
        end if
        call read_fe_group(f, deck, errors)
        call read_static_group(f, deck, errors)
    contains
        !> The &history groups of an estimation deck, each experiment's last
        !! time its last data row's (unknown: not checked).
        subroutine fit_histories()
            real(dp), allocatable :: t_end(:)
            character(len=1), allocatable :: none(:)
            integer :: e
            if (.not. allocated(deck%exp_names)) then
                allocate (none(0))
                call read_history_groups(f, none, [logical ::], [real(dp) ::], deck%hist, &
                                         errors)
                return
            end if
            allocate (t_end(size(deck%exp_names)), source=-1.0_dp)
            if (allocated(deck%row_exp) .and. allocated(deck%data%t)) then
                if (size(deck%row_exp) == size(deck%data%t)) then
                    do e = 1, size(t_end)
                        if (any(deck%row_exp == e)) t_end(e) = maxval(deck%data%t, &
                                                                      mask=deck%row_exp == e)
                    end do
                end if
            end if
            call read_history_groups(f, deck%exp_names, deck%exp_kind == EXP_RELEASE, t_end, &
                                     deck%hist, errors)
        end subroutine fit_histories
    end subroutine read_all

    !> One &published group: table, row, note, and equally long quantity,
    !! value and digits lists; deviation names quantities whose difference is
    !! documented, `kind` its class ('formulation', 'random draws' or
    !! 'unexplained'; beamid reproduce says 'last digit' by itself) and
    !! `section` the heading of docs/deviations.md that explains it.
    !! Appended to `text` in the format of deck_t%published.
    subroutine read_published(f, g, text, errors)
        type(nml_file_t), intent(in) :: f
        type(nml_group_t), intent(in) :: g
        character(len=:), allocatable, intent(inout) :: text, errors
        character(len=:), allocatable :: table, row, note, where, kind, section
        type(nml_text_t), allocatable :: quantity(:), deviation(:)
        real(dp), allocatable :: value(:)
        integer, allocatable :: digits(:)
        character(len=32) :: buffer
        character, parameter :: TAB = achar(9)
        integer :: nv, i, j, nerr
        logical :: given
        nerr = count_lines_alloc(errors)
        where = f%path//', line '//fmt_int(g%line)//': &published '
        call nml_check_keys(f, g, ' table row quantity value digits deviation note kind '// &
                            'section ', errors)
        table = ''
        row = ''
        note = ''
        kind = ''
        section = ''
        call nml_str(f, g, 'kind', kind, given, errors)
        call nml_str(f, g, 'section', section, given, errors)
        if (index(DEVIATION_KINDS, '|'//kind//'|') == 0) call add_error(errors, where// &
            "kind = '"//kind//"', expected 'formulation', 'random draws' or 'unexplained' "// &
            '(the class of its deviations, docs/deviations.md)')
        call nml_str(f, g, 'table', table, given, errors)
        call nml_str(f, g, 'row', row, given, errors)
        call nml_str(f, g, 'note', note, given, errors)
        call nml_strs(f, g, 'quantity', quantity, given, errors)
        call nml_strs(f, g, 'deviation', deviation, given, errors)
        call nml_ints(f, g, 'digits', digits, errors)
        nv = 0
        do j = 1, size(g%items)
            if (g%items(j)%key == 'value') nv = size(g%items(j)%values)
        end do
        allocate (value(nv))
        call nml_reals(f, g, 'value', value, nv, errors)
        if (count_lines_alloc(errors) > nerr) return
        if (size(quantity) == 0 .or. size(quantity) /= size(value) .or. &
            size(quantity) /= size(digits)) then
            call add_error(errors, where//'needs equally long quantity, value and digits '// &
                           'lists (got '//fmt_int(size(quantity))//', '//fmt_int(size(value))// &
                           ', '//fmt_int(size(digits))//')')
        end if
        if (count_lines_alloc(errors) > nerr) return
        text = text//'P'//TAB//untab(table)//TAB//untab(row)//TAB//untab(note)//new_line('a')
        if (len(kind) > 0) text = text//'K'//TAB//untab(kind)//TAB//untab(section)//new_line('a')
        do i = 1, size(quantity)
            write (buffer, '(es25.17e3)') value(i)
            text = text//'Q'//TAB//untab(quantity(i)%s)//TAB//trim(adjustl(buffer))//TAB// &
                   fmt_int(digits(i))//new_line('a')
        end do
        do i = 1, size(deviation)
            text = text//'D'//TAB//untab(deviation(i)%s)//new_line('a')
        end do
    contains
        pure function untab(s) result(out)
            character(len=*), intent(in) :: s
            character(len=len(s)) :: out
            integer :: k
            out = s
            do k = 1, len(s)
                if (s(k:k) == TAB .or. s(k:k) == new_line('a')) out(k:k) = ' '
            end do
        end function untab
    end subroutine read_published

    !> The groups a task takes.
    subroutine check_task_groups(f, task, is_fit, errors)
        type(nml_file_t), intent(in) :: f
        character(len=*), intent(in) :: task
        logical, intent(in) :: is_fit
        character(len=:), allocatable, intent(inout) :: errors
        integer :: k
        character(len=:), allocatable :: name, where
        do k = 1, size(f%groups)
            name = f%groups(k)%name
            if (index(KNOWN_GROUPS, ' '//name//' ') == 0) cycle
            if (nml_find(f, name) /= k) cycle
            where = f%path//', line '//fmt_int(f%groups(k)%line)//': '
            if (is_fit .and. index(FIT_GROUPS, ' '//name//' ') == 0) then
                call add_error(errors, where//'group &'//name//' does not belong in an '// &
                               'estimation deck, expected one of:'//FIT_GROUPS(:len_trim(FIT_GROUPS)))
            else if (.not. is_fit .and. task /= 'simulate' .and. name == 'history') then
                call add_error(errors, where//'group &history is only for task "simulate" '// &
                               'and the estimation tasks'//FIT_TASKS(:len_trim(FIT_TASKS)))
            else if (.not. is_fit .and. index(' experiment fit sensor ', ' '//name//' ') > 0) then
                call add_error(errors, where//'group &'//name//' is only for the estimation '// &
                               'tasks'//FIT_TASKS(:len_trim(FIT_TASKS)))
            else if (task /= 'simulate' .and. name == 'simulate') then
                call add_error(errors, where//'group &simulate is only for task "simulate"')
            else if (task == 'simulate' .and. index(' fe static ', ' '//name//' ') > 0) then
                call add_error(errors, where//'group &'//name//' is not used by task '// &
                               '"simulate" (give elements_per_beam in &simulate)')
            end if
        end do
    end subroutine check_task_groups

    !> Without a preset: effects off, the structure (NaN) must be given.
    pure function structure_base(nbeams) result(base)
        integer, intent(in) :: nbeams
        real(dp), allocatable :: base(:)
        integer, parameter :: structure(4) = [IB_L, IB_EI, IB_EA, IB_RHO]
        integer :: i, k
        allocate (base(param_count(nbeams)), source=0.0_dp)
        base([((param_index_beam(nbeams, i, structure(k)), k = 1, 4), i = 1, nbeams)]) = &
            ieee_value(1.0_dp, ieee_quiet_nan)
        base(param_index_global(nbeams, IG_AXIAL_COUPLING)) = 1.0_dp
        base(param_index_global(nbeams, IG_R_MOTOR)) = 1.0_dp
        base([(param_index_thickness(nbeams, i), i = 1, nbeams)]) = PACE_THICKNESS
    end function structure_base

    !> &model: arrays per beam / mass point / joint, scalars, named elbow and
    !! tip values (which override the arrays); a structure value missing
    !! without a preset is an error, and so is a nonphysical value.
    subroutine read_model(f, nbeams, base, has_preset, deck, errors)
        type(nml_file_t), intent(in) :: f
        integer, intent(in) :: nbeams
        real(dp), intent(in) :: base(:)
        logical, intent(in) :: has_preset
        type(deck_t), intent(inout) :: deck
        character(len=:), allocatable, intent(inout) :: errors
        character(len=*), parameter :: beam_keys(5) = [character(len=3) :: 'l', 'ei', 'ea', &
            'rho', 'c']
        integer, parameter :: beam_which(5) = [IB_L, IB_EI, IB_EA, IB_RHO, IB_C]
        character(len=*), parameter :: mass_keys(4) = [character(len=6) :: 'm', 'j', 'mu', &
            'c_drag']
        integer, parameter :: mass_which(4) = [IM_M, IM_J, IM_MU, IM_C]
        character(len=*), parameter :: global_keys(5) = [character(len=14) :: &
            'axial_coupling', 'root_flex', 'eta', 'r_motor', 'tau_motor']
        integer, parameter :: global_which(5) = [IG_AXIAL_COUPLING, IG_ROOT_FLEX, IG_ETA, &
            IG_R_MOTOR, IG_TAU_MOTOR]
        character(len=*), parameter :: named_keys(9) = [character(len=10) :: 'm_elbow', &
            'j_elbow', 'mu_elbow', 'c_elbow', 'elbow_flex', 'm_tip', 'j_tip', 'mu_tip', 'c_tip']
        integer, parameter :: named_which(9) = [IM_M, IM_J, IM_MU, IM_C, 0, IM_M, IM_J, IM_MU, &
                                                IM_C]   ! the elbow's (5: its flex), the tip's
        real(dp), allocatable :: params(:)
        integer :: k, i, im, idx, nerr
        logical :: given
        real(dp) :: x
        type(chain_t) :: chain
        type(status_t) :: st

        allocate (params(size(base)))
        params = base
        nerr = count_lines_alloc(errors)
        im = nml_find(f, 'model')
        if (im == 0 .and. .not. has_preset) then
            call add_error(errors, f%path//': group &model is missing (without a preset '// &
                           'give L, EI, EA and rho of every beam)')
        end if
        if (im > 0) then
            associate (g => f%groups(im))
                call nml_check_keys(f, g, ' l ei ea rho c m j mu c_drag joint_flex '// &
                                    'axial_coupling root_flex eta r_motor tau_motor m_elbow '// &
                                    'j_elbow mu_elbow c_elbow elbow_flex m_tip j_tip mu_tip '// &
                                    'c_tip thick ', errors)
                do k = 1, size(beam_keys)
                    call read_list(trim(beam_keys(k)), [(param_index_beam(nbeams, i, &
                                   beam_which(k)), i = 1, nbeams)], 'one per beam')
                end do
                do k = 1, size(mass_keys)
                    call read_list(trim(mass_keys(k)), [(param_index_mass(nbeams, i, &
                                   mass_which(k)), i = 1, nbeams)], &
                                   'one per mass point: the joints, then the tip')
                end do
                call read_list('joint_flex', [(param_index_joint_flex(nbeams, i), &
                                               i = 1, nbeams - 1)], 'one per joint')
                call read_list('thick', [(param_index_thickness(nbeams, i), i = 1, nbeams)], &
                               'one per beam')
                do k = 1, size(global_keys)
                    idx = param_index_global(nbeams, global_which(k))
                    call nml_real(f, g, trim(global_keys(k)), params(idx), given, errors)
                end do
                do k = 1, size(named_keys)
                    x = 0.0_dp
                    call nml_real(f, g, trim(named_keys(k)), x, given, errors)
                    if (.not. given) cycle
                    if (k <= 5 .and. nbeams < 2) then
                        call add_error(errors, f%path//': &model '//trim(named_keys(k))// &
                                       ' is given but the chain has one beam (no elbow)')
                        cycle
                    end if
                    if (k == 5) then
                        idx = param_index_joint_flex(nbeams, 1)
                    else
                        idx = param_index_mass(nbeams, merge(1, nbeams, k < 5), named_which(k))
                    end if
                    params(idx) = x
                end do
            end associate
        end if
        deck%params = params
        ! a value already reported is not reported again as missing
        if (count_lines_alloc(errors) > nerr) return
        do i = 1, size(params)
            if (ieee_is_nan(params(i))) call add_error(errors, f%path//': &model is missing '// &
                param_name(nbeams, i)//' (set it in &model, or use a preset)')
        end do
        if (count_lines_alloc(errors) > nerr) return
        call chain_from_vector(nbeams, params, chain, st)
        if (st%code /= STATUS_OK) call add_error(errors, f%path//': &'//trim(st%message))
        deck%model_ok = st%code == STATUS_OK
    contains
        !> A list of &model (key, one value per parameter ix, what it holds).
        subroutine read_list(key, ix, what)
            character(len=*), intent(in) :: key, what
            integer, intent(in) :: ix(:)
            real(dp) :: values(size(ix))
            integer :: n
            values = params(ix)
            call nml_reals(f, f%groups(im), key, values, n, errors, what)
            params(ix) = values
        end subroutine read_list
    end subroutine read_model

    pure integer function count_lines_alloc(errors)
        character(len=:), allocatable, intent(in) :: errors
        count_lines_alloc = 0
        if (allocated(errors)) count_lines_alloc = count_lines(errors)
    end function count_lines_alloc

    !> A tip load or a wire from a group (&load, &experiment): kind, fx, fy,
    !! moment, wire_length; `label` names the group in messages.
    subroutine read_load_values(f, g, label, arm, load, errors)
        type(nml_file_t), intent(in) :: f
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: label
        real(dp), intent(in) :: arm      !< total length of the chain (m)
        type(static_load_t), intent(out) :: load
        character(len=:), allocatable, intent(inout) :: errors
        character(len=:), allocatable :: kind
        logical :: given, has_wire, has_force(3)
        real(dp) :: values(4)
        values = 0.0_dp
        kind = ''
        call nml_str(f, g, 'kind', kind, given, errors)
        call nml_real(f, g, 'fx', values(1), has_force(1), errors)
        call nml_real(f, g, 'fy', values(2), has_force(2), errors)
        call nml_real(f, g, 'moment', values(3), has_force(3), errors)
        call nml_real(f, g, 'wire_length', values(4), has_wire, errors)
        load%fx = values(1)
        load%fy = values(2)
        load%moment = values(3)
        load%wire_length = 0.0_dp
        select case (trim(kind))
        case ('tip')
            load%kind = LOAD_TIP
            if (nml_given(g, 'wire_length')) call add_error(errors, label// &
                ": kind = 'tip' does not take wire_length")
        case ('wire')
            load%kind = LOAD_WIRE
            load%wire_length = values(4)
            if (.not. has_wire .and. nml_given(g, 'wire_length')) then
                continue    ! its value is already reported
            else if (.not. has_wire) then
                call add_error(errors, label//": kind = 'wire' needs wire_length (m)")
            else if (.not. values(4) > 0.0_dp) then
                call add_error(errors, label//': wire_length = '//fmt_g(values(4))// &
                               ', expected a length > 0 (m)')
            else if (values(4) >= arm .and. arm > 0.0_dp) then
                call add_error(errors, label//': wire_length = '//fmt_g(values(4))// &
                               ', expected a length shorter than the arm ('//fmt_g(arm)// &
                               ' m; a longer wire is slack)')
            end if
            if (any(values(1:3) /= 0.0_dp)) call add_error(errors, label// &
                ": kind = 'wire' does not take fx, fy or moment")
        case default
            load%kind = LOAD_TIP
            call add_error(errors, label//": kind = '"//trim(kind)//"', expected 'tip' or 'wire'")
        end select
    end subroutine read_load_values

    !> An &experiment: a static load (read_load_values), or kind = 'release'
    !! (issue 13): the tip load fx, fy, moment held before the release and
    !! the options of beamid.Release (elements_per_beam 4, motor_gain 0,
    !! integrator 'implicit' or 'rk4', rtol, dt, friction 'sign', 'smooth' or
    !! 'sign_literal'), in the spec ev (no key set for a static experiment).
    subroutine read_experiment(f, g, label, arm, load, ev, errors, kind_code)
        type(nml_file_t), intent(in) :: f
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: label
        real(dp), intent(in) :: arm
        type(static_load_t), intent(out) :: load
        type(experiment_spec_t), intent(out) :: ev
        character(len=:), allocatable, intent(inout) :: errors
        !> 0 static, EXP_RELEASE, EXP_MODAL (kind = 'modal', issue 27: the
        !! tip load held during the modal test and elements_per_beam)
        integer, intent(out) :: kind_code
        character(len=:), allocatable :: kind, text
        character(len=*), parameter :: dyn_keys(6) = [character(len=17) :: &
            'elements_per_beam', 'motor_gain', 'integrator', 'rtol', 'dt', 'friction']
        logical :: given
        integer :: nepb, i
        real(dp) :: x
        kind_code = 0
        kind = ''
        call nml_str(f, g, 'kind', kind, given, errors)
        if (trim(kind) == 'modal') then
            kind_code = EXP_MODAL
            do i = 2, size(dyn_keys)
                if (nml_given(g, trim(dyn_keys(i)))) call add_error(errors, label// &
                    ": kind = 'modal' does not take "//trim(dyn_keys(i))// &
                    " (only kind = 'release' does)")
            end do
            load%kind = LOAD_TIP
            call nml_real(f, g, 'fx', load%fx, given, errors)
            call nml_real(f, g, 'fy', load%fy, given, errors)
            call nml_real(f, g, 'moment', load%moment, given, errors)
            call set_load(ev, load)
            ! a radial wire held during the test (beamid_modal: the tip on its circle)
            if (nml_given(g, 'wire_length')) then
                x = 0.0_dp
                call nml_real(f, g, 'wire_length', x, given, errors)
                if (.not. x > 0.0_dp) then
                    call add_error(errors, label//': wire_length = '//fmt_g(x)// &
                                   ', expected a length > 0 (m)')
                else if (x >= arm .and. arm > 0.0_dp) then
                    call add_error(errors, label//': wire_length = '//fmt_g(x)// &
                                   ', expected a length shorter than the arm ('//fmt_g(arm)// &
                                   ' m; a longer wire is slack)')
                end if
                if (nml_given(g, 'fx') .or. nml_given(g, 'fy') .or. nml_given(g, 'moment')) &
                    call add_error(errors, label//": kind = 'modal' with wire_length does "// &
                                   "not take fx, fy or moment (the wire holds the arm)")
                call ev%set(EV_WIRE_LENGTH, x)
            end if
            nepb = 4
            call nml_int(f, g, 'elements_per_beam', nepb, given, errors)
            if (nepb < 1) call add_error(errors, label//': elements_per_beam = '// &
                                         fmt_int(nepb)//', expected at least 1')
            call ev%set(EV_NEPB, real(max(nepb, 1), dp))
            return
        end if
        if (trim(kind) /= 'release') then
            do i = 1, size(dyn_keys)
                if (nml_given(g, trim(dyn_keys(i)))) call add_error(errors, label// &
                    ": kind = '"//trim(kind)//"' does not take "//trim(dyn_keys(i))// &
                    " (only kind = 'release' does)")
            end do
            call read_load_values(f, g, label, arm, load, errors)
            return
        end if
        kind_code = EXP_RELEASE
        load%kind = LOAD_TIP
        call nml_real(f, g, 'fx', load%fx, given, errors)
        call nml_real(f, g, 'fy', load%fy, given, errors)
        call nml_real(f, g, 'moment', load%moment, given, errors)
        if (nml_given(g, 'wire_length')) call add_error(errors, label// &
            ": kind = 'release' does not take wire_length (the release is from a tip load)")
        call set_load(ev, load)
        nepb = 4
        call nml_int(f, g, 'elements_per_beam', nepb, given, errors)
        if (nepb < 1) call add_error(errors, label//': elements_per_beam = '//fmt_int(nepb)// &
                                     ', expected at least 1')
        call ev%set(EV_NEPB, real(max(nepb, 1), dp))
        x = 0.0_dp
        call nml_real(f, g, 'motor_gain', x, given, errors)
        if (x < 0.0_dp) call add_error(errors, label//': motor_gain = '//fmt_g(x)// &
                                       ', expected >= 0')
        call ev%set(EV_GAIN, max(x, 0.0_dp))
        text = 'implicit'
        call nml_str(f, g, 'integrator', text, given, errors)
        i = 0
        call read_choice(text, INTEGRATORS, [1, 0], "'", label//': integrator', i, errors)
        call ev%set(EV_METHOD, real(i, dp))
        text = 'sign'
        call nml_str(f, g, 'friction', text, given, errors)
        i = 0
        call read_choice(text, FRICTION_LAWS, [0, 1, 2], "'", label//': friction', i, errors)
        call ev%set(EV_LAW, real(i, dp))
        x = 0.0_dp
        call nml_real(f, g, 'rtol', x, given, errors)
        if (given .and. .not. x > 0.0_dp) call add_error(errors, label//': rtol = '// &
                                                         fmt_g(x)//', expected > 0')
        call ev%set(EV_RTOL, max(x, 0.0_dp))
        x = 0.0_dp
        call nml_real(f, g, 'dt', x, given, errors)
        if (given .and. .not. x > 0.0_dp) call add_error(errors, label//': dt = '// &
                                                         fmt_g(x)//', expected > 0 (s)')
        call ev%set(EV_DT, max(x, 0.0_dp))
    contains
        !> The tip load held (fx, fy, moment) into the spec.
        pure subroutine set_load(ev, load)
            type(experiment_spec_t), intent(inout) :: ev
            type(static_load_t), intent(in) :: load
            call ev%set(EV_FX, load%fx)
            call ev%set(EV_FY, load%fy)
            call ev%set(EV_MOMENT, load%moment)
        end subroutine set_load
    end subroutine read_experiment

    !> Total length of the deck's chain (0 when the model has errors).
    pure real(dp) function arm_length(deck)
        type(deck_t), intent(in) :: deck
        integer :: i
        arm_length = 0.0_dp
        if (.not. deck%model_ok) return
        do i = 1, deck%nbeams
            arm_length = arm_length + deck%params(param_index_beam(deck%nbeams, i, IB_L))
        end do
        if (ieee_is_nan(arm_length) .or. arm_length < 0.0_dp) arm_length = 0.0_dp
    end function arm_length

    !> &load (required except for fe_modes).
    subroutine read_load(f, deck, errors)
        type(nml_file_t), intent(in) :: f
        type(deck_t), intent(inout) :: deck
        character(len=:), allocatable, intent(inout) :: errors
        integer :: k
        k = nml_find(f, 'load')
        if (k == 0) then
            deck%load%kind = LOAD_TIP
            if (deck%task /= 'fe_modes') call add_error(errors, f%path//': group &load is '// &
                "missing (kind = 'tip' with fx, fy, moment, or kind = 'wire' with wire_length)")
            return
        end if
        deck%has_load = .true.
        associate (g => f%groups(k))
            call nml_check_keys(f, g, ' kind fx fy moment wire_length ', errors)
            call read_load_values(f, g, f%path//', line '//fmt_int(g%line)//': &load', &
                                  arm_length(deck), deck%load, errors)
        end associate
        if (deck%load%kind == LOAD_WIRE .and. deck%task /= 'static') call add_error(errors, &
            f%path//': &load kind = "wire" is not available for task "'//deck%task// &
            '" (tip loads only)')
    end subroutine read_load

    !> &fe (optional; tasks fe_static and fe_modes, docs/fe.md).
    subroutine read_fe_group(f, deck, errors)
        type(nml_file_t), intent(in) :: f
        type(deck_t), intent(inout) :: deck
        character(len=:), allocatable, intent(inout) :: errors
        character(len=:), allocatable :: moment_form, where
        integer :: k, epb, steps
        real(dp) :: tol
        logical :: given
        k = nml_find(f, 'fe')
        if (k == 0) return
        associate (g => f%groups(k))
            where = f%path//', line '//fmt_int(g%line)//': &fe '
            call nml_check_keys(f, g, ' elements_per_beam moment_form rotary_inertia '// &
                                'point_masses steps tol ', errors)
            epb = deck%fe_elements_per_beam
            steps = 0
            tol = 0.0_dp
            moment_form = 'eq78'
            call nml_int(f, g, 'elements_per_beam', epb, given, errors)
            call nml_str(f, g, 'moment_form', moment_form, given, errors)
            call nml_logical(f, g, 'rotary_inertia', deck%fe_rotary_inertia, given, errors)
            call nml_logical(f, g, 'point_masses', deck%fe_point_masses, given, errors)
            call nml_int(f, g, 'steps', steps, given, errors)
            call nml_real(f, g, 'tol', tol, given, errors)
            if (epb < 1) then
                call add_error(errors, where//'elements_per_beam = '//fmt_int(epb)// &
                               ', expected at least 1')
            else
                call check_mesh_size(where, deck%nbeams, epb, deck%task == 'fe_modes', 1, &
                                     errors)
            end if
            call read_choice(moment_form, [character(len=5) :: 'eq78', 'exact'], [0, 1], "'", &
                             where//'moment_form', deck%fe_moment_form, errors)
            if (steps < 0) call add_error(errors, where//'steps = '//fmt_int(steps)// &
                                          ', expected 0 (default) or a positive count')
            if (tol < 0.0_dp) call add_error(errors, where//'tol = '//fmt_g(tol)// &
                                             ', expected 0 (default) or a positive tolerance')
            deck%fe_elements_per_beam = epb
            deck%fe_steps = steps
            deck%fe_tol = tol
        end associate
    end subroutine read_fe_group

    !> code = codes(i) when text is words(i); else an error '<key> = <q>text<q>,
    !! expected <q>words(1)<q>, ... or <q>words(n)<q>' (key: the group's label
    !! and the key) and code unchanged.
    subroutine read_choice(text, words, codes, q, key, code, errors)
        character(len=*), intent(in) :: text, words(:), q, key
        integer, intent(in) :: codes(:)
        integer, intent(inout) :: code
        character(len=:), allocatable, intent(inout) :: errors
        character(len=:), allocatable :: list
        integer :: i
        i = findloc(words, trim(text), 1)
        if (i > 0) code = codes(i)
        if (i > 0) return
        list = ' or '//q//trim(words(size(words)))//q
        do i = size(words) - 1, 1, -1
            list = q//trim(words(i))//q//list
            if (i > 1) list = ', '//list
        end do
        call add_error(errors, key//' = '//q//trim(text)//q//', expected '//list)
    end subroutine read_choice

    !> Memory bound of a mesh: nbeams*epb elements, 4 unknowns per node; the
    !! banded solvers keep about 40 numbers per unknown, the modes (dense
    !! eigenproblem) 3 n^2, a history `nt` states of 2 n.
    subroutine check_mesh_size(where, nbeams, epb, dense, nt, errors)
        character(len=*), intent(in) :: where
        integer, intent(in) :: nbeams, epb, nt
        logical, intent(in) :: dense
        character(len=:), allocatable, intent(inout) :: errors
        real(dp) :: nfree, bytes
        nfree = 4.0_dp*(real(nbeams, dp)*real(epb, dp) + 1.0_dp)
        bytes = 8.0_dp*(40.0_dp*nfree + 2.0_dp*nfree*real(nt, dp))
        if (dense) bytes = bytes + 8.0_dp*3.0_dp*nfree**2
        if (bytes > MAX_BYTES) call add_error(errors, where//'elements_per_beam = '// &
            fmt_int(epb)//': the computation would need about '//fmt_bytes(bytes)// &
            ' of memory (limit '//fmt_bytes(MAX_BYTES)//')')
    end subroutine check_mesh_size


    !> &static (optional; task static).
    subroutine read_static_group(f, deck, errors)
        type(nml_file_t), intent(in) :: f
        type(deck_t), intent(inout) :: deck
        character(len=:), allocatable, intent(inout) :: errors
        type(nml_text_t), allocatable :: wrt(:)
        character(len=:), allocatable :: where
        integer :: k, i, n
        real(dp) :: tol
        logical :: given
        allocate (deck%wrt(0))
        k = nml_find(f, 'static')
        if (k == 0) return
        associate (g => f%groups(k))
            where = f%path//', line '//fmt_int(g%line)//': &static '
            call nml_check_keys(f, g, ' wrt shape_points tol ', errors)
            call nml_strs(f, g, 'wrt', wrt, given, errors)
            n = deck%shape_points
            tol = 0.0_dp
            call nml_int(f, g, 'shape_points', n, given, errors)
            call nml_real(f, g, 'tol', tol, given, errors)
            deck%wrt = [(param_lookup(deck%nbeams, wrt(i)%s), i = 1, size(wrt))]
            do i = 1, size(wrt)
                if (deck%wrt(i) == 0) call add_error(errors, where//"wrt = '"//wrt(i)%s// &
                    "' is not a parameter name (e.g. EI1, C2, elbow_flex)")
            end do
            if (n < 0 .or. n == 1) then
                call add_error(errors, where//'shape_points = '//fmt_int(n)// &
                               ', expected 0 (no shape) or at least 2')
            else if (5.0_dp*8.0_dp*real(n, dp) > MAX_BYTES) then
                call add_error(errors, where//'shape_points = '//fmt_int(n)// &
                               ': the shape would need about '//fmt_bytes(40.0_dp*real(n, dp))// &
                               ' of memory (limit '//fmt_bytes(MAX_BYTES)//')')
            end if
            if (.not. (tol >= 0.0_dp .and. tol < 1.0e-2_dp)) call add_error(errors, where// &
                'tol = '//fmt_real(tol)//', expected 0 (default) or a tolerance below 1e-2')
            deck%shape_points = n
            deck%tol = tol
        end associate
    end subroutine read_static_group

    !> &simulate of a dynamic deck (task simulate): the output times (t_out,
    !! or t_end with n_out equally spaced times from 0), the mesh, the
    !! integrator and the friction law; 0 means the default for dt, rtol,
    !! atol and friction_velocity.
    subroutine read_simulate_group(f, deck, errors)
        type(nml_file_t), intent(in) :: f
        type(deck_t), intent(inout) :: deck
        character(len=:), allocatable, intent(inout) :: errors
        real(dp), allocatable :: t_out(:)
        real(dp) :: t_end, step, values(5)
        integer :: n_out, epb, k, i, nt, j
        character(len=:), allocatable :: integrator, friction, where
        logical :: has_end, has_n, given, has_t_out, end_ok, n_ok
        character(len=*), parameter :: names(5) = [character(len=17) :: 'dt', 'rtol', &
            'atol', 'friction_velocity', 'motor_gain']

        allocate (deck%sim_t_out(0))
        k = nml_find(f, 'simulate')
        if (k == 0) then
            call add_error(errors, f%path//': group &simulate is missing (t_out, or t_end '// &
                           'and n_out)')
            return
        end if
        associate (g => f%groups(k))
            where = f%path//', line '//fmt_int(g%line)//': &simulate '
            call nml_check_keys(f, g, ' t_out t_end n_out elements_per_beam integrator dt '// &
                                'rtol atol motor_gain friction friction_velocity ', errors)
            ! a list of times holds at most one value per item token
            nt = 0
            do j = 1, size(g%items)
                if (g%items(j)%key == 't_out') nt = g%items(j)%first - 1 + size(g%items(j)%values)
            end do
            allocate (t_out(nt))
            t_out = ieee_value(1.0_dp, ieee_quiet_nan)
            call nml_reals(f, g, 't_out', t_out, nt, errors)
            t_end = 0.0_dp
            n_out = 101
            epb = 4
            integrator = 'implicit'
            friction = ''
            values = 0.0_dp
            call nml_real(f, g, 't_end', t_end, end_ok, errors)
            call nml_int(f, g, 'n_out', n_out, n_ok, errors)
            call nml_int(f, g, 'elements_per_beam', epb, given, errors)
            call nml_str(f, g, 'integrator', integrator, given, errors)
            call nml_str(f, g, 'friction', friction, given, errors)
            do i = 1, size(names)
                call nml_real(f, g, trim(names(i)), values(i), given, errors)
            end do
            has_t_out = nml_given(g, 't_out')
            has_end = nml_given(g, 't_end')
            has_n = nml_given(g, 'n_out')
            if (has_t_out .and. has_end) then
                call add_error(errors, where//'gives both t_out and t_end: give one')
            else if (.not. has_t_out .and. .not. has_end) then
                call add_error(errors, where//'needs t_out (a list of output times) or '// &
                               't_end (with n_out)')
            else if (has_t_out .and. has_n) then
                call add_error(errors, where//'n_out goes with t_end, not with t_out')
            else if (has_t_out) then
                if (nt > MAX_TIMES) then
                    call add_error(errors, where//'t_out has '//fmt_int(nt)// &
                                   ' times, expected at most '//fmt_int(MAX_TIMES))
                else if (any(ieee_is_nan(t_out(1:nt)))) then
                    call add_error(errors, where//'t_out has gaps: give the output times '// &
                                   'as one list')
                else
                    deck%sim_t_out = t_out(1:nt)
                end if
            else if (end_ok .and. (n_ok .or. .not. has_n)) then
                if (.not. (t_end > 0.0_dp)) then
                    call add_error(errors, where//'t_end = '//fmt_g(t_end)// &
                                   ', expected a time > 0 (s)')
                else if (n_out < 2) then
                    call add_error(errors, where//'n_out = '//fmt_int(n_out)// &
                                   ', expected at least 2')
                else if (n_out > MAX_TIMES) then
                    call add_error(errors, where//'n_out = '//fmt_int(n_out)// &
                                   ': the history would need about '// &
                                   fmt_bytes(8.0_dp*16.0_dp*real(n_out, dp))//' or more of memory '// &
                                   '(at most '//fmt_int(MAX_TIMES)//' output times)')
                else
                    ! numpy.linspace(0, t_end, n_out), to the last bit
                    step = t_end/real(n_out - 1, dp)
                    deck%sim_t_out = [(real(i, dp)*step, i = 0, n_out - 1)]
                    deck%sim_t_out(n_out) = t_end
                end if
            end if
            do i = 1, size(deck%sim_t_out)
                if (i == 1 .and. deck%sim_t_out(i) < 0.0_dp) exit
                if (i > 1) then
                    if (deck%sim_t_out(i) <= deck%sim_t_out(i - 1)) exit
                end if
            end do
            if (i <= size(deck%sim_t_out)) call add_error(errors, where//'t_out must be '// &
                'ascending times >= 0 (entry '//fmt_int(i)//' = '//fmt_g(deck%sim_t_out(i))//')')
            if (epb < 1) then
                call add_error(errors, where//'elements_per_beam = '//fmt_int(epb)// &
                               ', expected at least 1')
            else
                call check_mesh_size(where, deck%nbeams, epb, .false., &
                                     max(1, size(deck%sim_t_out)), errors)
            end if
            call read_choice(integrator, INTEGRATORS, [1, 0], '"', where//'integrator', &
                             deck%sim_integrator, errors)
            ! '': the sign law (events) for both integrators
            if (len_trim(friction) == 0) friction = 'sign'
            call read_choice(friction, FRICTION_LAWS, [0, 1, 2], '"', where//'friction', &
                             deck%sim_friction, errors)
            do i = 1, size(names) - 1
                if (values(i) < 0.0_dp) call add_error(errors, where//trim(names(i))//' = '// &
                    fmt_g(values(i))//', expected 0 (default) or a positive number')
            end do
            if (values(5) < 0.0_dp) call add_error(errors, where//'motor_gain = '// &
                fmt_g(values(5))//', expected a finite number >= 0')
            deck%sim_elements_per_beam = epb
            deck%sim_dt = values(1)
            deck%sim_rtol = values(2)
            deck%sim_atol = values(3)
            if (values(4) > 0.0_dp) deck%sim_friction_velocity = values(4)
            deck%sim_motor_gain = values(5)
        end associate
    end subroutine read_simulate_group

    !> The groups of an estimation deck after &beamid and &model: every
    !! &experiment (repeatable) and &fit, whose measurement CSV is read here.
    subroutine read_fit_groups(f, deck, errors)
        type(nml_file_t), intent(in) :: f
        type(deck_t), intent(inout) :: deck
        character(len=:), allocatable, intent(inout) :: errors
        character(len=:), allocatable :: name, label, where, free_list
        type(static_load_t), allocatable :: loads(:)
        type(nml_text_t), allocatable :: names(:)
        logical, allocatable :: is_wire(:), has_motor(:)
        integer, allocatable :: kinds(:)
        type(experiment_spec_t), allocatable :: especs(:)
        type(experiment_spec_t) :: ev
        logical :: given
        integer :: ne, k, i, ig, maxlen, nerr, nf, kcode
        type(static_load_t) :: load
        type(nml_group_t) :: gx
        type(stage_t), allocatable :: stages(:)

        ! ---- &experiment, one group per experiment
        nerr = count_lines_alloc(errors)
        ne = nml_count(f, 'experiment')
        allocate (names(0), loads(0), kinds(0), especs(0))
        do k = 1, ne
            ig = nml_find(f, 'experiment', k)
            gx = f%groups(ig)
            call nml_check_keys(f, gx, ' name kind fx fy moment wire_length '// &
                                'elements_per_beam motor_gain integrator rtol dt friction ', &
                                errors)
            name = ''
            call nml_str(f, gx, 'name', name, given, errors)
            name = trim(adjustl(name))
            where = f%path//', line '//fmt_int(gx%line)//': '
            if (len(name) == 0) then
                call add_error(errors, where//'&experiment number '//fmt_int(k)// &
                               ' has no name')
                name = '#'//fmt_int(k)
            end if
            gx%label = "&experiment '"//name//"'"
            label = where//gx%label
            do i = 1, size(names)
                if (names(i)%s == name) call add_error(errors, where// &
                    "&experiment name = '"//name//"' defined twice")
            end do
            call read_experiment(f, gx, label, arm_length(deck), load, ev, errors, kcode)
            names = [names, nml_text_t(name)]
            loads = [loads, load]
            kinds = [kinds, kcode]
            especs = [especs, ev]
        end do
        if (ne == 0) call add_error(errors, f%path//': no &experiment groups: define at '// &
                                    'least one experiment')
        maxlen = 1
        do i = 1, size(names)
            maxlen = max(maxlen, len(names(i)%s))
        end do
        allocate (character(len=maxlen) :: deck%exp_names(size(names)))
        do i = 1, size(names)
            deck%exp_names(i) = names(i)%s
        end do
        deck%experiments = loads
        deck%exp_kind = kinds
        deck%exp_specs = especs
        is_wire = loads%kind == LOAD_WIRE .and. kinds == 0
        has_motor = kinds == EXP_RELEASE .and. especs%get(EV_GAIN) > 0.0_dp

        call read_sensor_groups(f, deck, errors)

        ! ---- &fit: one group, or for task identify one per stage, in order
        deck%candidates = default_effects(FAMILY_STATIC)
        ! modal tests alone: the modal family's defaults (as beamid.diagnose)
        if (size(kinds) > 0) then
            if (all(kinds == EXP_MODAL)) deck%candidates = default_effects(FAMILY_MODAL)
        end if
        nf = nml_count(f, 'fit')
        if (nf == 0) then
            call add_error(errors, f%path//': group &fit is missing (data, free)')
            return
        end if
        if (nf > 1 .and. deck%task /= 'identify') then
            ig = nml_find(f, 'fit', 2)
            call add_error(errors, f%path//', line '//fmt_int(f%groups(ig)%line)// &
                           ': group &fit appears '//fmt_int(nf)//" times (once only; several "// &
                           "&fit groups are the stages of task 'identify')")
            nf = 1
        end if
        allocate (stages(nf))
        do k = 1, nf
            call read_fit_group(f, f%groups(nml_find(f, 'fit', k)), k, deck, is_wire, kinds, &
                                has_motor, nerr, stages(k), errors)
            do i = 1, k - 1
                if (stages(i)%name == stages(k)%name) call add_error(errors, f%path// &
                    ', line '//fmt_int(f%groups(nml_find(f, 'fit', k))%line)// &
                    ": &fit stage = '"//stages(k)%name//"' names two stages")
            end do
        end do
        call take_stage(deck, stages(1))   ! the deck's own fit is its first (only) stage
        do k = 1, nf
            if (.not. allocated(stages(k)%logger_experiment)) cycle
            if (len(stages(k)%logger_experiment) == 0) cycle
            deck%channel_text = deck%channel_text//'C'//achar(9)//fmt_int(k)//achar(9)// &
                                stages(k)%logger_experiment//achar(9)// &
                                fmt_g(stages(k)%logger_sigma)//new_line('a')
        end do
        if (deck%task /= 'identify') return
        call move_alloc(stages, deck%stages)   ! not copied: see copy_measurements
        associate (stages => deck%stages)
        ! one line per stage for the Python reader: 'S name data free max_iter'
        ! (tab separated, free as 1-based indices separated by commas)
        deck%stage_text = ''
        do k = 1, nf
            free_list = ''
            do i = 1, size(stages(k)%free)
                if (i > 1) free_list = free_list//','
                free_list = free_list//fmt_int(stages(k)%free(i))
            end do
            deck%stage_text = deck%stage_text//'S'//achar(9)//stages(k)%name//achar(9)// &
                              stages(k)%data_path//achar(9)//free_list//achar(9)// &
                              fmt_int(stages(k)%max_iter)//new_line('a')
        end do
        end associate
    end subroutine read_fit_groups

    !> The fit of a stage as the deck's: its data, rows, free parameters, a
    !! priori values and iteration limit.
    subroutine take_stage(deck, stage)
        type(deck_t), intent(inout) :: deck
        type(stage_t), intent(in) :: stage
        deck%free = stage%free
        deck%prior_index = stage%prior_index
        deck%prior_mean = stage%prior_mean
        deck%prior_sigma = stage%prior_sigma
        deck%max_iter = stage%max_iter
        if (allocated(stage%data_path)) deck%data_path = stage%data_path
        call copy_measurements(stage%data, deck%data)
        if (allocated(stage%row_exp)) deck%row_exp = stage%row_exp
    end subroutine take_stage

    !> dst = src for measurements. (gfortran 12's intrinsic assignment of a
    !! derived type with a deferred-length character array component, as
    !! measurements_t%experiment, allocates the array one element long and
    !! copies past its end: copy the components one by one instead.)
    subroutine copy_measurements(src, dst)
        type(measurements_t), intent(in) :: src
        type(measurements_t), intent(out) :: dst
        if (allocated(src%source)) dst%source = src%source
        if (allocated(src%experiment)) then
            allocate (character(len=len(src%experiment)) :: dst%experiment(size(src%experiment)))
            dst%experiment(:) = src%experiment(:)
        end if
        if (allocated(src%t)) dst%t = src%t
        if (allocated(src%quantity)) dst%quantity = src%quantity
        if (allocated(src%obs)) dst%obs = src%obs
        if (allocated(src%value)) dst%value = src%value
        if (allocated(src%sigma)) dst%sigma = src%sigma
        if (allocated(src%line)) dst%line = src%line
    end subroutine copy_measurements

    !> One &fit group: the data CSV (its rows checked against the
    !! experiments when no error was found since error count `nerr`), free parameters, a priori
    !! information, candidates, alpha, max_iter; for task identify the
    !! stage's name (`stage`, default stage<k>), a priori information on the
    !! first stage only (a later stage's is the previous fit, Eq. 146-148).
    subroutine read_fit_group(f, g, k, deck, is_wire, kinds, has_motor, nerr, stage, errors)
        type(nml_file_t), intent(in) :: f
        type(nml_group_t), intent(in) :: g
        integer, intent(in) :: k, nerr
        type(deck_t), intent(inout) :: deck
        logical, intent(in) :: is_wire(:), has_motor(:)
        integer, intent(in) :: kinds(:)
        type(stage_t), intent(out) :: stage
        character(len=:), allocatable, intent(inout) :: errors
        character(len=:), allocatable :: where, data, free_list, name
        type(nml_text_t), allocatable :: free(:), prior_names(:), candidates(:)
        real(dp), allocatable :: prior_means(:), prior_sigmas(:)
        integer, allocatable :: block(:)
        logical :: given, identify
        integer :: i, np, nm, ns, kk, slash
        type(status_t) :: st

        identify = deck%task == 'identify'
        allocate (stage%free(0), stage%prior_index(0), stage%prior_mean(0), stage%prior_sigma(0))
        where = f%path//', line '//fmt_int(g%line)//': &fit '
        call nml_check_keys(f, g, ' data free prior_names prior_means prior_sigmas '// &
                            'candidates alpha max_iter stage logger_experiment logger_sigma'// &
                            CHAIN_KEYS, errors)
        data = ''
        stage%logger_experiment = ''
        call nml_str(f, g, 'logger_experiment', stage%logger_experiment, given, errors)
        stage%logger_experiment = trim(adjustl(stage%logger_experiment))
        call nml_real(f, g, 'logger_sigma', stage%logger_sigma, given, errors)
        name = 'stage'//fmt_int(k)
        call nml_str(f, g, 'data', data, given, errors)
        call nml_str(f, g, 'stage', name, given, errors)
        name = trim(adjustl(name))
        if (given .and. .not. identify) call add_error(errors, where//"stage = '"//name// &
            "': stages belong to task 'identify' (one &fit group per stage)")
        if (given .and. (len(name) == 0 .or. index(name, ',') > 0 .or. &
                         index(name, achar(9)) > 0)) then
            call add_error(errors, where//"stage = '"//name//"', expected a name without "// &
                           'commas')
            name = 'stage'//fmt_int(k)
        end if
        stage%name = name
        if (identify) where = where//"(stage '"//name//"') "
        call nml_strs(f, g, 'free', free, given, errors)
        call nml_strs(f, g, 'prior_names', prior_names, given, errors)
        call nml_strs(f, g, 'candidates', candidates, given, errors)
        np = size(prior_names)
        nm = 0
        ns = 0
        do i = 1, size(g%items)
            if (g%items(i)%key == 'prior_means') nm = size(g%items(i)%values)
            if (g%items(i)%key == 'prior_sigmas') ns = size(g%items(i)%values)
        end do
        allocate (prior_means(nm), prior_sigmas(ns))
        call nml_reals(f, g, 'prior_means', prior_means, nm, errors)
        call nml_reals(f, g, 'prior_sigmas', prior_sigmas, ns, errors)
        call nml_real(f, g, 'alpha', deck%alpha, given, errors)
        call nml_int(f, g, 'max_iter', stage%max_iter, given, errors)
        if (identify .and. (size(candidates) > 0 .or. nml_given(g, 'alpha'))) &
            call add_error(errors, where//"candidates and alpha are not used by task "// &
                           "'identify' (diagnose a stage's deck on its own)")
        if (identify .and. k > 1 .and. max(np, nm, ns) > 0) call add_error(errors, where// &
            'prior_names: the a priori information of a later stage is the previous '// &
            "stage's fit, carried forward (Eq. 146-148); give a priori values in the first")

        free_list = ''
        do i = 1, size(free)
            kk = param_lookup(deck%nbeams, free(i)%s)
            if (kk == 0) then
                call add_error(errors, where//"free = '"//free(i)%s// &
                               "' is not a parameter name")
                cycle
            end if
            if (any(stage%free == kk)) then
                call add_error(errors, where//"free names parameter '"// &
                               param_name(deck%nbeams, kk)//"' twice")
                cycle
            end if
            stage%free = [stage%free, kk]
            if (len(free_list) > 0) free_list = free_list//', '
            free_list = free_list//param_name(deck%nbeams, kk)
        end do
        if (size(free) == 0) call add_error(errors, where//'free is missing: name the '// &
                                            'parameters to estimate')
        if (np /= size(prior_means) .or. np /= size(prior_sigmas)) then
            call add_error(errors, where//'prior_names, prior_means and prior_sigmas '// &
                           'must have equal lengths (got '//fmt_int(np)//', '// &
                           fmt_int(size(prior_means))//', '//fmt_int(size(prior_sigmas))//')')
        else
            stage%prior_index = [(param_lookup(deck%nbeams, prior_names(i)%s), i = 1, np)]
            stage%prior_mean = prior_means
            stage%prior_sigma = prior_sigmas
            do i = 1, np
                kk = stage%prior_index(i)
                if (kk == 0) then
                    call add_error(errors, where//"prior_names = '"//prior_names(i)%s// &
                                   "' is not a parameter name")
                else if (.not. any(stage%free == kk)) then
                    call add_error(errors, where//"prior_names = '"//prior_names(i)%s// &
                                   "' is not free (free: "//free_list//')')
                end if
                if (.not. prior_sigmas(i) > 0.0_dp) call add_error(errors, where// &
                    "prior for '"//prior_names(i)%s//"' = ("//fmt_g(prior_means(i))// &
                    ', '//fmt_g(prior_sigmas(i))//'), expected a finite mean and sigma > 0')
            end do
        end if
        if (size(candidates) > 0 .and. .not. identify) then
            deallocate (deck%candidates)
            allocate (deck%candidates(size(candidates)))
            do i = 1, size(candidates)
                deck%candidates(i) = candidates(i)%s
                ! the measurement chain's row candidates (beamid_ladder row_rung)
                if (candidates(i)%s == 'gross_errors' .or. candidates(i)%s == 'noise') cycle
                call effect_params(deck%nbeams, deck%candidates(i), block, st)
                if (st%code /= STATUS_OK) then
                    call add_error(errors, where//"candidates = '"//candidates(i)%s// &
                                   "' is not a known effect, expected one of: "// &
                                   known_effects())
                    st%code = STATUS_OK
                end if
            end do
        end if
        if (.not. (deck%alpha > 0.0_dp .and. deck%alpha < 1.0_dp)) call add_error(errors, &
            where//'alpha = '//fmt_g(deck%alpha)//', expected a significance level in (0, 1)')
        if (stage%max_iter < 1) call add_error(errors, where//'max_iter = '// &
                                               fmt_int(stage%max_iter)//', expected at least 1')
        ! the data: read only when the experiments are valid
        if (len_trim(data) == 0) then
            call add_error(errors, where//'data is missing: give the measurement CSV file')
            return
        end if
        if (data(1:1) == '/') then
            stage%data_path = trim(data)
        else
            slash = index(f%path, '/', back=.true.)
            stage%data_path = f%path(:slash)//trim(data)
        end if
        if (nml_given(g, 'logger_sigma') .and. .not. stage%logger_sigma > 0.0_dp) &
            call add_error(errors, where//'logger_sigma = '//fmt_g(stage%logger_sigma)// &
                           ', expected a sigma > 0')
        if (nml_given(g, 'logger_sigma') .and. len(stage%logger_experiment) == 0) &
            call add_error(errors, where//'logger_sigma is given without logger_experiment '// &
                           '(the experiment a logger file records)')
        if (len(stage%logger_experiment) > 0) then
            if (.not. any(deck%exp_names == stage%logger_experiment)) then
                call add_error(errors, where//"logger_experiment = '"// &
                               stage%logger_experiment//"' is not defined (experiments: "// &
                               join_names(deck%exp_names)//')')
                return
            end if
            call read_channel_file(stage%data_path, stage%logger_experiment, deck%sensors, &
                                   stage%logger_sigma, stage%data, st)
        else
            call read_measurements(stage%data_path, stage%data, st)
        end if
        if (st%code == STATUS_OK .and. size(kinds) > 0 .and. count_lines_alloc(errors) == nerr) &
            call check_static_rows(stage%data, deck%exp_names, is_wire, stage%row_exp, st, &
                                   kinds == EXP_RELEASE, has_motor, deck_lengths(deck), &
                                   kinds == EXP_MODAL)
        if (st%code /= STATUS_OK) call add_error(errors, f%path//', line '// &
            fmt_int(g%line)//': &fit data: '//trim(st%message))
        if (st%code /= STATUS_OK .or. .not. allocated(stage%row_exp)) return
        if (count_lines_alloc(errors) /= nerr) return
        call read_chain_keys(f, g, where, identify, deck, stage, errors)
        if (count_lines_alloc(errors) /= nerr) return
        i = chain_sigma_missing(deck%exp_specs, stage%row_exp, stage%data%obs, &
                                stage%data%sigma)
        if (i > 0) call add_error(errors, where//'data: sigma missing: '// &
            stage%data_path//', line '//fmt_int(stage%data%line(i))//' has no sigma '// &
            "(an empty field) and no estimation is asked; expected a sigma > 0 on every "// &
            "row, or estimate_sigma = 'all' (or naming its channel)")
    end subroutine read_fit_group

    !> The &sensor groups (name, observation, sigma): the channels of a
    !! logger file with names of their own (docs/rig.md).
    subroutine read_sensor_groups(f, deck, errors)
        type(nml_file_t), intent(in) :: f
        type(deck_t), intent(inout) :: deck
        character(len=:), allocatable, intent(inout) :: errors
        type(nml_group_t) :: g
        type(observation_t) :: o
        character(len=:), allocatable :: name, obs, where, why
        type(nml_text_t), allocatable :: names(:), obss(:)
        real(dp), allocatable :: sig(:)
        real(dp) :: sigma
        logical :: given
        integer :: k, i, n
        n = nml_count(f, 'sensor')
        allocate (names(0), obss(0), sig(0))
        deck%channel_text = ''
        do k = 1, n
            g = f%groups(nml_find(f, 'sensor', k))
            where = f%path//', line '//fmt_int(g%line)//': &sensor '
            call nml_check_keys(f, g, ' name observation sigma ', errors)
            name = ''
            obs = ''
            sigma = 0.0_dp
            call nml_str(f, g, 'name', name, given, errors)
            call nml_str(f, g, 'observation', obs, given, errors)
            call nml_real(f, g, 'sigma', sigma, given, errors)
            name = trim(adjustl(name))
            obs = trim(adjustl(obs))
            if (len(name) == 0 .or. index(name, ',') > 0 .or. index(name, achar(9)) > 0) &
                call add_error(errors, where//"name = '"//name//"', expected a channel name "// &
                               '(no commas)')
            call parse_observation(obs, o, why)
            if (len(why) > 0 .or. len(obs) == 0) then
                if (len(obs) == 0) why = 'observation is missing'
                call add_error(errors, where//"'"//name//"': observation = '"//obs//"': "//why)
            end if
            if (given .and. .not. sigma > 0.0_dp) call add_error(errors, where//"'"//name// &
                "': sigma = "//fmt_g(sigma)//', expected a sigma > 0')
            do i = 1, size(names)
                if (names(i)%s == name) call add_error(errors, where//"name = '"//name// &
                                                       "' defined twice")
            end do
            names = [names, nml_text_t(name)]
            obss = [obss, nml_text_t(obs)]
            sig = [sig, sigma]
        end do
        allocate (deck%sensors(size(names)))
        do i = 1, size(names)
            deck%sensors(i)%name = names(i)%s
            deck%sensors(i)%observation = obss(i)%s
            deck%sensors(i)%sigma = sig(i)
            deck%channel_text = deck%channel_text//'N'//achar(9)//names(i)%s//achar(9)// &
                                obss(i)%s//achar(9)//fmt_g(sig(i))//new_line('a')
        end do
    end subroutine read_sensor_groups

    !> Names joined by ', ' ('none' for none).
    pure function join_names(names) result(text)
        character(len=*), intent(in) :: names(:)
        character(len=:), allocatable :: text
        integer :: i
        text = 'none'
        if (size(names) == 0) return
        text = trim(names(1))
        do i = 2, size(names)
            text = text//', '//trim(names(i))
        end do
    end function join_names
    !> The measurement chain's keys of a &fit group (beamid_chain_deck:
    !! time_offset, bias, scale, loss, burn_in, estimate_sigma,
    !! initial_velocity) into the
    !! experiments' specs; not for task identify.
    subroutine read_chain_keys(f, g, where, identify, deck, stage, errors)
        type(nml_file_t), intent(in) :: f
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: where
        logical, intent(in) :: identify
        type(deck_t), intent(inout) :: deck
        type(stage_t), intent(in) :: stage
        character(len=:), allocatable, intent(inout) :: errors
        character(len=*), parameter :: keys(6) = [character(len=16) :: 'time_offset', 'bias', &
                                                  'scale', 'loss', 'estimate_sigma', &
                                                  'initial_velocity']
        type(nml_text_t), allocatable :: items(:)
        character(len=40) :: text
        logical :: given
        real(dp) :: t
        integer :: k
        do k = 1, size(keys)
            if (.not. nml_given(g, trim(keys(k)))) cycle
            if (identify) then
                call add_error(errors, where//trim(keys(k))//' is not used by task '// &
                               "'identify' (fit a stage's deck on its own)")
                cycle
            end if
            call nml_strs(f, g, trim(keys(k)), items, given, errors)
            call set_chain_key(trim(keys(k)), items, deck%exp_names, deck%exp_kind, &
                               stage%row_exp, stage%data%obs, deck%exp_specs, where, errors)
        end do
        if (.not. nml_given(g, 'burn_in')) return
        if (identify) then
            call add_error(errors, where//"burn_in is not used by task 'identify'")
            return
        end if
        t = -1.0_dp
        call nml_real(f, g, 'burn_in', t, given, errors)
        write (text, '(es24.17)') t
        call set_chain_key('burn_in', [nml_text_t(trim(adjustl(text)))], deck%exp_names, &
                           deck%exp_kind, stage%row_exp, stage%data%obs, deck%exp_specs, &
                           where, errors)
    end subroutine read_chain_keys

    !> The beam lengths of the deck's model (empty before the model is read).
    pure function deck_lengths(deck) result(lengths)
        type(deck_t), intent(in) :: deck
        real(dp), allocatable :: lengths(:)
        integer :: b
        allocate (lengths(0))
        if (.not. allocated(deck%params) .or. deck%nbeams < 1) return
        if (size(deck%params) /= param_count(deck%nbeams)) return
        lengths = [(deck%params(param_index_beam(deck%nbeams, b, IB_L)), b=1, deck%nbeams)]
    end function deck_lengths

    !> Run a deck with another task (`beamid fit|compare|diagnose|improve
    !! DECK`): a blank `task` keeps the deck's; an estimation task replaces
    !! the task of an estimation deck only.
    subroutine deck_set_task(d, task, stat)
        type(deck_t), intent(inout) :: d
        character(len=*), intent(in) :: task
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: estimation = ' fit compare diagnose improve '
        if (len_trim(task) == 0 .or. trim(task) == d%task) return
        if (index(estimation, ' '//trim(task)//' ') > 0 .and. &
            index(estimation, ' '//d%task//' ') > 0) then
            d%task = trim(task)
        else
            stat%code = ERR_INPUT
            stat%message = trim(d%path)//": task '"//trim(task)//"' cannot run a deck of task '"// &
                           d%task//"' (fit, compare, diagnose and improve run estimation decks)"
        end if
    end subroutine deck_set_task
end module beamid_deck
