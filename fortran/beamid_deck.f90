!> Namelist input decks for the batch executable (format: docs/decks.md).
!!
!! A deck holds the groups &beamid (task, output, preset, nbeams), &model
!! (per-beam and per-mass-point arrays and the effect parameters), &load and
!! &static. Estimation decks (tasks fit, compare, diagnose, improve) hold
!! &beamid, &model, one &experiment per experiment and &fit, whose data CSV
!! is read and validated here too (beamid_measurements). Every group and
!! variable is checked: an unknown group, a misspelt variable, a missing
!! value or a nonphysical one is reported with the deck's path and the
!! offending name. Dynamic decks (task simulate) hold &beamid, &model,
!! &load (the tip load held before the release) and &simulate.
module beamid_deck
    use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_nan
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_IO, ERR_DECK, ERR_INPUT, STATUS_OK, &
                             fmt_int, fmt_real, lower
    use beamid_model, only: param_count, param_name, param_index_beam, param_index_mass, &
                            param_index_joint_flex, param_index_global, chain_t, &
                            chain_from_vector, IB_L, IB_EI, IB_EA, IB_RHO, IB_C, IM_M, IM_J, &
                            IM_MU, IM_C, IG_AXIAL_COUPLING, IG_ROOT_FLEX, IG_ETA, IG_R_MOTOR, &
                            IG_TAU_MOTOR
    use beamid_presets, only: preset_params
    use beamid_arclength, only: static_load_t, LOAD_TIP, LOAD_WIRE
    use beamid_static_experiments, only: static_effect_params, EFFECT_NAMES, NEFFECT
    use beamid_measurements, only: measurements_t, read_measurements, check_static_rows, fmt_g
    implicit none
    private

    public :: deck_t, read_deck, param_lookup, KNOWN_GROUPS

    integer, parameter :: NAME_LEN = 32
    character(len=*), parameter :: KNOWN_GROUPS = &
        ' beamid model load static fe published experiment fit simulate '
    !> Tasks the batch runs.
    character(len=*), parameter :: KNOWN_TASKS = &
        ' static fe_static fe_modes fit compare diagnose improve simulate '
    !> Estimation tasks and the groups their decks may hold.
    character(len=*), parameter :: FIT_TASKS = ' fit compare diagnose improve '
    character(len=*), parameter :: FIT_GROUPS = ' beamid model experiment fit published '
    !> Groups that may appear more than once.
    character(len=*), parameter :: REPEATABLE = ' experiment published '

    !> Everything a deck says.
    type :: deck_t
        character(len=:), allocatable :: path
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
        character(len=:), allocatable :: data_path      !< measurement CSV
        type(measurements_t) :: data
        integer, allocatable :: row_exp(:)              !< experiment index of each data row
        integer, allocatable :: free(:)                 !< parameter indices to estimate
        integer, allocatable :: prior_index(:)          !< a priori (Eq. 142-145)
        real(dp), allocatable :: prior_mean(:), prior_sigma(:)
        character(len=NAME_LEN), allocatable :: candidates(:) !< effects for diagnose/improve
        real(dp) :: alpha = 0.01_dp
        integer :: max_iter = 50
        ! &simulate (task simulate; docs/decks.md, Dynamic decks): the arguments of
        ! beamid.simulate, defaults resolved as there
        real(dp), allocatable :: sim_t_out(:)           !< output times (s)
        integer :: sim_elements_per_beam = 4
        integer :: sim_integrator = 1                   !< 0 rk4, 1 implicit
        integer :: sim_friction = 0                     !< 0 sign, 1 smooth, 2 sign_literal
        real(dp) :: sim_dt = 0.0_dp                     !< 0: default (1e-5 s)
        real(dp) :: sim_rtol = 0.0_dp                   !< 0: default (1e-7)
        real(dp) :: sim_atol = 0.0_dp                   !< 0: rtol
        real(dp) :: sim_motor_gain = 0.0_dp
        real(dp) :: sim_friction_velocity = 1.0e-4_dp   !< smooth law's vs (m/s)
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

    !> Read and validate a deck.
    subroutine read_deck(path, deck, stat)
        character(len=*), intent(in) :: path
        type(deck_t), intent(out) :: deck
        type(status_t), intent(inout) :: stat

        ! &beamid
        character(len=NAME_LEN) :: task, preset
        character(len=1024) :: output
        integer :: nbeams
        ! &model (allocated once nbeams is known)
        real(dp), allocatable :: L(:), EI(:), EA(:), rho(:), C(:)
        real(dp), allocatable :: m(:), J(:), mu(:), c_drag(:), joint_flex(:)
        real(dp) :: axial_coupling, root_flex, eta, r_motor, tau_motor
        ! named scalars for the elbow (joint 1) and the tip; they override the arrays
        real(dp) :: m_elbow, J_elbow, mu_elbow, c_elbow, elbow_flex
        real(dp) :: m_tip, J_tip, mu_tip, c_tip
        ! &load
        character(len=NAME_LEN) :: kind
        real(dp) :: fx, fy, moment, wire_length
        ! &fe
        integer :: elements_per_beam, steps
        character(len=NAME_LEN) :: moment_form
        logical :: rotary_inertia, point_masses
        ! &static
        character(len=NAME_LEN), allocatable :: wrt(:)
        integer :: shape_points
        real(dp) :: tol

        namelist /beamid/ task, output, preset, nbeams
        namelist /model/ L, EI, EA, rho, C, m, J, mu, c_drag, joint_flex, axial_coupling, &
            root_flex, eta, r_motor, tau_motor, m_elbow, J_elbow, mu_elbow, c_elbow, &
            elbow_flex, m_tip, J_tip, mu_tip, c_tip
        namelist /load/ kind, fx, fy, moment, wire_length
        namelist /static/ wrt, shape_points, tol
        namelist /fe/ elements_per_beam, moment_form, rotary_inertia, point_masses, steps, tol

        integer :: unit, ios, i, nb_preset, nw
        character(len=512) :: msg
        character(len=:), allocatable :: present
        real(dp) :: nan
        real(dp), allocatable :: base(:)
        logical :: exists, is_fit

        deck%path = path
        nan = ieee_value(1.0_dp, ieee_quiet_nan)
        inquire (file=path, exist=exists)
        if (.not. exists) then
            call set_status(stat, ERR_IO, 'deck', 'cannot open '//trim(path)// &
                            ': no such file')
            return
        end if
        open (newunit=unit, file=path, status='old', action='read', iostat=ios, iomsg=msg)
        if (ios /= 0) then
            call set_status(stat, ERR_IO, 'deck', 'cannot open '//trim(path)//': '//trim(msg))
            return
        end if
        call check_groups(unit, path, present, stat)
        if (stat%code /= STATUS_OK) then
            close (unit)
            return
        end if

        ! ---- &beamid
        task = 'static'
        output = ''
        preset = ''
        nbeams = 0
        rewind (unit)
        read (unit, nml=beamid, iostat=ios, iomsg=msg)
        if (ios /= 0) then
            call group_error('beamid', ios, msg)
            return
        end if
        if (index(KNOWN_TASKS, ' '//trim(task)//' ') == 0 .or. len_trim(task) == 0) then
            call deck_error('&beamid task = "'//trim(task)//'", expected one of:'// &
                            KNOWN_TASKS(:len_trim(KNOWN_TASKS)))
            return
        end if
        is_fit = index(FIT_TASKS, ' '//trim(task)//' ') > 0
        ! the groups of the task (check_groups returned those present)
        do i = 1, len(present)
            if (present(i:i) /= '&') cycle
            nw = index(present(i + 1:), ' ')
            if (is_fit .and. index(FIT_GROUPS, ' '//present(i + 1:i + nw)) == 0) then
                call deck_error('unknown group &'//present(i + 1:i + nw - 1)// &
                                ' in an estimation deck, expected one of:'// &
                                FIT_GROUPS(:len_trim(FIT_GROUPS)))
                return
            else if (.not. is_fit .and. index(' experiment fit ', &
                                              ' '//present(i + 1:i + nw)) > 0) then
                call deck_error('group &'//present(i + 1:i + nw - 1)//' is only for the '// &
                                'estimation tasks'//FIT_TASKS(:len_trim(FIT_TASKS)))
                return
            else if (trim(task) /= 'simulate' .and. present(i + 1:i + nw) == 'simulate ') then
                call deck_error('group &simulate is only for task "simulate"')
                return
            else if (trim(task) == 'simulate' .and. index(' fe static ', &
                                                         ' '//present(i + 1:i + nw)) > 0) then
                call deck_error('group &'//present(i + 1:i + nw - 1)//' is not used by '// &
                                'task "simulate" (give elements_per_beam in &simulate)')
                return
            end if
        end do
        ! estimation decks start from the PACE arm unless they name another preset
        if (is_fit .and. len_trim(preset) == 0) preset = 'pace'
        if (len_trim(output) == 0) then
            call deck_error('&beamid output is missing: give the output path prefix')
            return
        end if
        if (len_trim(preset) > 0) then
            call preset_params(trim(preset), nb_preset, base, stat)
            if (stat%code /= STATUS_OK) then
                stat%message = trim(path)//': &beamid '//trim(stat%message)
                close (unit)
                return
            end if
            if (nbeams == 0) nbeams = nb_preset
            if (nbeams /= nb_preset) then
                call deck_error('&beamid nbeams = '//fmt_int(nbeams)//' but preset "'// &
                                trim(preset)//'" has '//fmt_int(nb_preset)//' beams')
                return
            end if
        else
            if (nbeams < 1) then
                call deck_error('&beamid nbeams = '//fmt_int(nbeams)// &
                                ': give nbeams >= 1 or a preset ("pace", "cantilever")')
                return
            end if
            allocate (base(param_count(nbeams)))
            base = nan
            ! effects default to their null values; the structure must be given
            do i = 1, nbeams
                base(param_index_mass(nbeams, i, IM_M)) = 0.0_dp
                base(param_index_mass(nbeams, i, IM_J)) = 0.0_dp
                base(param_index_beam(nbeams, i, IB_C)) = 0.0_dp
            end do
            base(param_index_joint_flex(nbeams, 1):) = 0.0_dp
            base(param_index_global(nbeams, IG_AXIAL_COUPLING)) = 1.0_dp
            base(param_index_global(nbeams, IG_R_MOTOR)) = 1.0_dp
            do i = 1, nbeams
                base(param_index_mass(nbeams, i, IM_MU)) = 0.0_dp
                base(param_index_mass(nbeams, i, IM_C)) = 0.0_dp
            end do
        end if
        deck%nbeams = nbeams
        deck%task = trim(task)
        deck%output = trim(output)

        ! ---- &model (optional with a preset)
        allocate (L(nbeams), EI(nbeams), EA(nbeams), rho(nbeams), C(nbeams))
        allocate (m(nbeams), J(nbeams), mu(nbeams), c_drag(nbeams), joint_flex(nbeams - 1))
        do i = 1, nbeams
            L(i) = base(param_index_beam(nbeams, i, IB_L))
            EI(i) = base(param_index_beam(nbeams, i, IB_EI))
            EA(i) = base(param_index_beam(nbeams, i, IB_EA))
            rho(i) = base(param_index_beam(nbeams, i, IB_RHO))
            C(i) = base(param_index_beam(nbeams, i, IB_C))
            m(i) = base(param_index_mass(nbeams, i, IM_M))
            J(i) = base(param_index_mass(nbeams, i, IM_J))
            mu(i) = base(param_index_mass(nbeams, i, IM_MU))
            c_drag(i) = base(param_index_mass(nbeams, i, IM_C))
        end do
        do i = 1, nbeams - 1
            joint_flex(i) = base(param_index_joint_flex(nbeams, i))
        end do
        axial_coupling = base(param_index_global(nbeams, IG_AXIAL_COUPLING))
        root_flex = base(param_index_global(nbeams, IG_ROOT_FLEX))
        eta = base(param_index_global(nbeams, IG_ETA))
        r_motor = base(param_index_global(nbeams, IG_R_MOTOR))
        tau_motor = base(param_index_global(nbeams, IG_TAU_MOTOR))
        m_elbow = nan
        J_elbow = nan
        mu_elbow = nan
        c_elbow = nan
        elbow_flex = nan
        m_tip = nan
        J_tip = nan
        mu_tip = nan
        c_tip = nan
        rewind (unit)
        read (unit, nml=model, iostat=ios, iomsg=msg)
        if (ios > 0 .or. (ios < 0 .and. len_trim(preset) == 0)) then
            call group_error('model', ios, msg)
            return
        end if
        call take(m(nbeams), m_tip)
        call take(J(nbeams), J_tip)
        call take(mu(nbeams), mu_tip)
        call take(c_drag(nbeams), c_tip)
        if (nbeams >= 2) then
            call take(m(1), m_elbow)
            call take(J(1), J_elbow)
            call take(mu(1), mu_elbow)
            call take(c_drag(1), c_elbow)
            call take(joint_flex(1), elbow_flex)
        else if (.not. all(ieee_is_nan([m_elbow, J_elbow, mu_elbow, c_elbow, elbow_flex]))) then
            call deck_error('&model sets an elbow parameter but the chain has one beam')
            return
        end if
        allocate (deck%params(param_count(nbeams)))
        do i = 1, nbeams
            deck%params(param_index_beam(nbeams, i, IB_L)) = L(i)
            deck%params(param_index_beam(nbeams, i, IB_EI)) = EI(i)
            deck%params(param_index_beam(nbeams, i, IB_EA)) = EA(i)
            deck%params(param_index_beam(nbeams, i, IB_RHO)) = rho(i)
            deck%params(param_index_beam(nbeams, i, IB_C)) = C(i)
            deck%params(param_index_mass(nbeams, i, IM_M)) = m(i)
            deck%params(param_index_mass(nbeams, i, IM_J)) = J(i)
            deck%params(param_index_mass(nbeams, i, IM_MU)) = mu(i)
            deck%params(param_index_mass(nbeams, i, IM_C)) = c_drag(i)
        end do
        do i = 1, nbeams - 1
            deck%params(param_index_joint_flex(nbeams, i)) = joint_flex(i)
        end do
        deck%params(param_index_global(nbeams, IG_AXIAL_COUPLING)) = axial_coupling
        deck%params(param_index_global(nbeams, IG_ROOT_FLEX)) = root_flex
        deck%params(param_index_global(nbeams, IG_ETA)) = eta
        deck%params(param_index_global(nbeams, IG_R_MOTOR)) = r_motor
        deck%params(param_index_global(nbeams, IG_TAU_MOTOR)) = tau_motor
        do i = 1, size(deck%params)
            if (ieee_is_nan(deck%params(i)) .and. ieee_is_nan(base(i))) then
                call deck_error('&model is missing '//param_name(nbeams, i)// &
                                ' (set it in &model, or use a preset)')
                return
            end if
        end do
        block
            type(chain_t) :: chain
            call chain_from_vector(nbeams, deck%params, chain, stat)
        end block
        if (stat%code /= STATUS_OK) then
            stat%message = trim(path)//': &'//trim(stat%message)
            close (unit)
            return
        end if
        if (is_fit) then
            call read_fit_groups(unit, path, deck, stat)
            close (unit)
            return
        end if

        ! ---- &load (required)
        kind = ''
        fx = 0.0_dp
        fy = 0.0_dp
        moment = 0.0_dp
        wire_length = nan
        rewind (unit)
        read (unit, nml=load, iostat=ios, iomsg=msg)
        if (ios < 0 .and. trim(task) == 'fe_modes') then
            kind = 'tip'
        else if (ios /= 0) then
            call group_error('load', ios, msg)
            return
        else
            deck%has_load = .true.
        end if
        select case (trim(kind))
        case ('tip')
            deck%load%kind = LOAD_TIP
            if (.not. ieee_is_nan(wire_length)) then
                call deck_error('&load kind = "tip" does not take wire_length')
                return
            end if
            wire_length = 0.0_dp
        case ('wire')
            deck%load%kind = LOAD_WIRE
            if (ieee_is_nan(wire_length)) then
                call deck_error('&load kind = "wire" needs wire_length (m)')
                return
            end if
            if (fx /= 0.0_dp .or. fy /= 0.0_dp .or. moment /= 0.0_dp) then
                call deck_error('&load kind = "wire" does not take fx, fy or moment')
                return
            end if
        case default
            call deck_error('&load kind = "'//trim(kind)//'", expected "tip" or "wire"')
            return
        end select
        deck%load%fx = fx
        deck%load%fy = fy
        deck%load%moment = moment
        deck%load%wire_length = wire_length
        if (trim(task) == 'simulate') then
            call read_simulate_group(unit, path, deck, stat)
            close (unit)
            return
        end if

        ! ---- &fe (optional)
        elements_per_beam = 4
        moment_form = 'eq78'
        rotary_inertia = .false.
        point_masses = .true.
        steps = 0
        tol = 0.0_dp
        rewind (unit)
        read (unit, nml=fe, iostat=ios, iomsg=msg)
        if (ios > 0) then
            call group_error('fe', ios, msg)
            return
        end if
        if (elements_per_beam < 1) then
            call deck_error('&fe elements_per_beam = '//fmt_int(elements_per_beam)// &
                            ', expected at least 1')
            return
        end if
        select case (trim(moment_form))
        case ('eq78')
            deck%fe_moment_form = 0
        case ('exact')
            deck%fe_moment_form = 1
        case default
            call deck_error('&fe moment_form = "'//trim(moment_form)// &
                            '", expected "eq78" or "exact"')
            return
        end select
        if (steps < 0 .or. .not. (tol >= 0.0_dp)) then
            call deck_error('&fe steps and tol must not be negative (0: default)')
            return
        end if
        if (deck%load%kind == LOAD_WIRE .and. task(1:3) == 'fe_') then
            call deck_error('&load kind = "wire" is not available for task "'//trim(task)// &
                            '" (tip loads only)')
            return
        end if
        deck%fe_elements_per_beam = elements_per_beam
        deck%fe_rotary_inertia = rotary_inertia
        deck%fe_point_masses = point_masses
        deck%fe_steps = steps
        deck%fe_tol = tol

        ! ---- &static (optional)
        allocate (wrt(param_count(nbeams)))
        wrt = ''
        shape_points = 101
        tol = 0.0_dp
        rewind (unit)
        read (unit, nml=static, iostat=ios, iomsg=msg)
        if (ios > 0) then
            call group_error('static', ios, msg)
            return
        end if
        close (unit)
        nw = count(len_trim(wrt) > 0)
        allocate (deck%wrt(nw))
        do i = 1, nw
            deck%wrt(i) = param_lookup(nbeams, wrt(i))
            if (deck%wrt(i) == 0) then
                call set_status(stat, ERR_DECK, trim(path), '&static wrt = "'//trim(wrt(i))// &
                                '" is not a parameter name (e.g. EI1, C2, elbow_flex)')
                return
            end if
        end do
        if (shape_points < 0 .or. shape_points == 1) then
            call set_status(stat, ERR_DECK, trim(path), '&static shape_points = '// &
                            fmt_int(shape_points)//', expected 0 (no shape) or at least 2')
            return
        end if
        if (.not. (tol >= 0.0_dp .and. tol < 1.0e-2_dp)) then
            call set_status(stat, ERR_DECK, trim(path), '&static tol = '//fmt_real(tol)// &
                            ', expected 0 (default) or a tolerance below 1e-2')
            return
        end if
        deck%shape_points = shape_points
        deck%tol = tol

    contains

        !> A named scalar, when given, overrides the array entry.
        pure subroutine take(entry, named)
            real(dp), intent(inout) :: entry
            real(dp), intent(in) :: named
            if (.not. ieee_is_nan(named)) entry = named
        end subroutine take

        subroutine deck_error(text)
            character(len=*), intent(in) :: text
            call set_status(stat, ERR_DECK, trim(path), text)
            close (unit)
        end subroutine deck_error

        subroutine group_error(group, iostat, iomsg)
            character(len=*), intent(in) :: group
            integer, intent(in) :: iostat
            character(len=*), intent(in) :: iomsg
            if (iostat < 0) then
                call deck_error('group &'//group//' is missing')
            else
                call deck_error('in &'//group//': '//trim(iomsg))
            end if
        end subroutine group_error
    end subroutine read_deck

    !> &simulate of a dynamic deck (task simulate), after &load: the output
    !! times (t_out, or t_end with n_out equally spaced times from 0), the mesh,
    !! the integrator and the friction law; 0 means the default for dt, rtol,
    !! atol and friction_velocity. The checks and messages are those of
    !! beamid.decks (same order), so a deck fails the same way in both.
    subroutine read_simulate_group(unit, path, deck, stat)
        integer, intent(in) :: unit
        character(len=*), intent(in) :: path
        type(deck_t), intent(inout) :: deck
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: t_out(:)
        real(dp) :: t_end, dt, rtol, atol, motor_gain, friction_velocity, nan, step
        integer :: n_out, elements_per_beam
        character(len=NAME_LEN) :: integrator, friction
        namelist /simulate/ t_out, t_end, n_out, elements_per_beam, integrator, dt, rtol, &
            atol, motor_gain, friction, friction_velocity
        character(len=512) :: msg
        character(len=*), parameter :: names(4) = [character(len=17) :: 'dt', 'rtol', &
            'atol', 'friction_velocity']
        real(dp) :: values(4)
        integer :: ios, i, nt, fsize

        if (deck%load%kind == LOAD_WIRE) then
            call fail('&load kind = "wire" is not available for task "simulate" (tip loads '// &
                      'only)')
            return
        end if
        nan = ieee_value(1.0_dp, ieee_quiet_nan)
        ! a list of times cannot hold more values than the deck has characters
        inquire (unit=unit, size=fsize)
        allocate (t_out(max(16, fsize/2 + 1)))
        t_out = nan
        t_end = nan
        n_out = -1
        elements_per_beam = 4
        integrator = 'implicit'
        friction = ''
        dt = 0.0_dp
        rtol = 0.0_dp
        atol = 0.0_dp
        motor_gain = 0.0_dp
        friction_velocity = 0.0_dp
        rewind (unit)
        read (unit, nml=simulate, iostat=ios, iomsg=msg)
        if (ios < 0) then
            call fail('group &simulate is missing')
            return
        else if (ios > 0) then
            call fail('in &simulate: '//trim(msg))
            return
        end if
        nt = count(.not. ieee_is_nan(t_out))
        if (any(ieee_is_nan(t_out(1:nt)))) then
            call fail('&simulate t_out has gaps: give the output times as one list')
            return
        end if
        if (nt > 0 .and. .not. ieee_is_nan(t_end)) then
            call fail('&simulate gives both t_out and t_end: give one')
            return
        end if
        if (nt == 0 .and. ieee_is_nan(t_end)) then
            call fail('&simulate needs t_out (a list of output times) or t_end (with n_out)')
            return
        end if
        if (nt > 0 .and. n_out /= -1) then
            call fail('&simulate n_out goes with t_end, not with t_out')
            return
        end if
        if (nt > 0) then
            deck%sim_t_out = t_out(1:nt)
        else
            if (.not. (t_end > 0.0_dp .and. t_end <= huge(1.0_dp))) then
                call fail('&simulate t_end = '//fmt_g(t_end)//', expected a time > 0 (s)')
                return
            end if
            if (n_out == -1) n_out = 101
            if (n_out < 2) then
                call fail('&simulate n_out = '//fmt_int(n_out)//', expected at least 2')
                return
            end if
            ! numpy.linspace(0, t_end, n_out), to the last bit
            step = t_end/real(n_out - 1, dp)
            deck%sim_t_out = [(real(i, dp)*step, i = 0, n_out - 1)]
            deck%sim_t_out(n_out) = t_end
        end if
        do i = 1, size(deck%sim_t_out)
            if (.not. abs(deck%sim_t_out(i)) <= huge(1.0_dp)) exit
            if (i == 1 .and. deck%sim_t_out(i) < 0.0_dp) exit
            if (i > 1) then
                if (deck%sim_t_out(i) <= deck%sim_t_out(i - 1)) exit
            end if
        end do
        if (i <= size(deck%sim_t_out)) then
            call fail('&simulate t_out must be ascending times >= 0 (entry '//fmt_int(i)// &
                      ' = '//fmt_g(deck%sim_t_out(i))//')')
            return
        end if
        if (elements_per_beam < 1) then
            call fail('&simulate elements_per_beam = '//fmt_int(elements_per_beam)// &
                      ', expected at least 1')
            return
        end if
        select case (trim(integrator))
        case ('rk4')
            deck%sim_integrator = 0
        case ('implicit')
            deck%sim_integrator = 1
        case default
            call fail('&simulate integrator = "'//trim(integrator)// &
                      '", expected "implicit" or "rk4"')
            return
        end select
        select case (trim(friction))
        case ('')
            deck%sim_friction = 0   ! the sign law (events) for both integrators
        case ('sign')
            deck%sim_friction = 0
        case ('smooth')
            deck%sim_friction = 1
        case ('sign_literal')
            deck%sim_friction = 2
        case default
            call fail('&simulate friction = "'//trim(friction)// &
                      '", expected "sign", "smooth" or "sign_literal"')
            return
        end select
        values = [dt, rtol, atol, friction_velocity]
        do i = 1, size(values)
            if (.not. (values(i) >= 0.0_dp .and. values(i) <= huge(1.0_dp))) then
                call fail('&simulate '//trim(names(i))//' = '//fmt_g(values(i))// &
                          ', expected 0 (default) or a positive number')
                return
            end if
        end do
        if (.not. (motor_gain >= 0.0_dp .and. motor_gain <= huge(1.0_dp))) then
            call fail('&simulate motor_gain = '//fmt_g(motor_gain)// &
                      ', expected a finite number >= 0')
            return
        end if
        deck%sim_elements_per_beam = elements_per_beam
        deck%sim_dt = dt
        deck%sim_rtol = rtol
        deck%sim_atol = atol
        deck%sim_motor_gain = motor_gain
        if (friction_velocity > 0.0_dp) deck%sim_friction_velocity = friction_velocity

    contains

        subroutine fail(text)
            character(len=*), intent(in) :: text
            call set_status(stat, ERR_DECK, trim(path), text)
        end subroutine fail
    end subroutine read_simulate_group

    !> The groups of an estimation deck after &beamid and &model: every
    !! &experiment (repeatable, read in turn without rewinding) and &fit, whose
    !! measurement CSV is read here (the order of checks of the Python reader,
    !! beamid.fit_decks.read_fit_deck, so both report the same first error).
    subroutine read_fit_groups(unit, path, deck, stat)
        integer, intent(in) :: unit
        character(len=*), intent(in) :: path
        type(deck_t), intent(inout) :: deck
        type(status_t), intent(inout) :: stat
        integer, parameter :: MAX_CANDIDATES = 4*NEFFECT
        ! &experiment
        character(len=256) :: name
        character(len=NAME_LEN) :: kind
        real(dp) :: fx, fy, moment, wire_length
        ! &fit
        character(len=1024) :: data
        character(len=NAME_LEN), allocatable :: free(:), prior_names(:), candidates(:)
        real(dp), allocatable :: prior_means(:), prior_sigmas(:)
        real(dp) :: alpha
        integer :: max_iter
        namelist /experiment/ name, kind, fx, fy, moment, wire_length
        namelist /fit/ data, free, prior_names, prior_means, prior_sigmas, candidates, alpha, &
            max_iter

        character(len=256), allocatable :: names(:)
        character(len=512) :: msg
        character(len=:), allocatable :: label, free_list
        type(static_load_t) :: load
        type(static_load_t), allocatable :: loads(:)
        integer :: ios, i, k, n, np, nm, ns, maxlen, slash
        integer, allocatable :: block(:)
        logical, allocatable :: is_wire(:)
        real(dp) :: nan

        nan = ieee_value(1.0_dp, ieee_quiet_nan)
        ! ---- &experiment, one group per experiment
        allocate (names(0), loads(0))
        rewind (unit)
        k = 0
        do
            name = ''
            kind = ''
            fx = 0.0_dp
            fy = 0.0_dp
            moment = 0.0_dp
            wire_length = nan
            read (unit, nml=experiment, iostat=ios, iomsg=msg)
            if (ios < 0) exit
            k = k + 1
            if (ios > 0) then
                call fail('in &experiment number '//fmt_int(k)//': '//trim(msg))
                return
            end if
            if (len_trim(name) == 0) then
                call fail('&experiment number '//fmt_int(k)//' has no name')
                return
            end if
            label = "&experiment '"//trim(name)//"'"
            if (any(names == name)) then
                call fail("&experiment name = '"//trim(name)//"' defined twice")
                return
            end if
            load = static_load_t()
            select case (trim(kind))
            case ('tip')
                if (.not. ieee_is_nan(wire_length)) then
                    call fail(label//": kind = 'tip' does not take wire_length")
                    return
                end if
                load%kind = LOAD_TIP
                load%fx = fx
                load%fy = fy
                load%moment = moment
                load%wire_length = 0.0_dp
            case ('wire')
                if (ieee_is_nan(wire_length)) then
                    call fail(label//": kind = 'wire' needs wire_length (m)")
                    return
                end if
                if (fx /= 0.0_dp .or. fy /= 0.0_dp .or. moment /= 0.0_dp) then
                    call fail(label//": kind = 'wire' does not take fx, fy or moment")
                    return
                end if
                load%kind = LOAD_WIRE
                load%wire_length = wire_length
            case default
                call fail(label//": kind = '"//trim(kind)//"', expected 'tip' or 'wire'")
                return
            end select
            names = [names, name]
            loads = [loads, load]
        end do
        if (size(names) == 0) then
            call fail('no &experiment groups: define at least one experiment')
            return
        end if
        maxlen = maxval(len_trim(names))
        allocate (character(len=maxlen) :: deck%exp_names(size(names)))
        do i = 1, size(names)
            deck%exp_names(i) = names(i)
        end do
        deck%experiments = loads
        is_wire = loads%kind == LOAD_WIRE

        ! ---- &fit
        n = param_count(deck%nbeams)
        allocate (free(n), prior_names(n), prior_means(n), prior_sigmas(n))
        allocate (candidates(MAX_CANDIDATES))
        data = ''
        free = ''
        prior_names = ''
        prior_means = nan
        prior_sigmas = nan
        candidates = ''
        alpha = 0.01_dp
        max_iter = 50
        rewind (unit)
        read (unit, nml=fit, iostat=ios, iomsg=msg)
        if (ios < 0) then
            call fail('group &fit is missing')
            return
        else if (ios > 0) then
            call fail('in &fit: '//trim(msg))
            return
        end if
        if (len_trim(data) == 0) then
            call fail('&fit data is missing: give the measurement CSV file')
            return
        end if
        if (data(1:1) == '/') then
            deck%data_path = trim(data)
        else
            slash = index(path, '/', back=.true.)
            deck%data_path = path(:slash)//trim(data)
        end if
        call read_measurements(deck%data_path, deck%data, stat)
        if (stat%code /= STATUS_OK) return
        call check_static_rows(deck%data, deck%exp_names, is_wire, deck%row_exp, stat)
        if (stat%code /= STATUS_OK) return

        deck%free = [integer ::]
        free_list = ''
        do i = 1, n
            if (len_trim(free(i)) == 0) cycle
            k = param_lookup(deck%nbeams, free(i))
            if (k == 0) then
                call fail("&fit free = '"//trim(free(i))//"' is not a parameter name")
                return
            end if
            if (any(deck%free == k)) then
                call fail("&fit free names parameter '"//param_name(deck%nbeams, k)//"' twice")
                return
            end if
            deck%free = [deck%free, k]
            if (len(free_list) > 0) free_list = free_list//', '
            free_list = free_list//param_name(deck%nbeams, k)
        end do
        if (size(deck%free) == 0) then
            call fail('&fit free is missing: name the parameters to estimate')
            return
        end if

        np = count(len_trim(prior_names) > 0)
        nm = count(.not. ieee_is_nan(prior_means))
        ns = count(.not. ieee_is_nan(prior_sigmas))
        if (np /= nm .or. np /= ns) then
            call fail('&fit prior_names, prior_means and prior_sigmas must have equal '// &
                      'lengths (got '//fmt_int(np)//', '//fmt_int(nm)//', '//fmt_int(ns)//')')
            return
        end if
        allocate (deck%prior_index(np), deck%prior_mean(np), deck%prior_sigma(np))
        do i = 1, np
            k = param_lookup(deck%nbeams, prior_names(i))
            if (k == 0) then
                call fail("&fit prior_names = '"//trim(prior_names(i))// &
                          "' is not a parameter name")
                return
            end if
            if (.not. any(deck%free == k)) then
                call fail("&fit prior_names = '"//trim(prior_names(i))//"' is not free "// &
                          '(free: '//free_list//')')
                return
            end if
            if (.not. (abs(prior_means(i)) <= huge(1.0_dp) .and. prior_sigmas(i) > 0.0_dp &
                       .and. prior_sigmas(i) <= huge(1.0_dp))) then
                call fail("&fit prior for '"//trim(prior_names(i))//"' = ("// &
                          fmt_g(prior_means(i))//', '//fmt_g(prior_sigmas(i))// &
                          '), expected a finite mean and sigma > 0')
                return
            end if
            deck%prior_index(i) = k
            deck%prior_mean(i) = prior_means(i)
            deck%prior_sigma(i) = prior_sigmas(i)
        end do

        n = count(len_trim(candidates) > 0)
        if (n == 0) then
            deck%candidates = EFFECT_NAMES
        else
            deck%candidates = pack(candidates, len_trim(candidates) > 0)
        end if
        do i = 1, size(deck%candidates)
            call static_effect_params(deck%nbeams, deck%candidates(i), block, stat)
            if (stat%code /= STATUS_OK) then
                call clear_and_fail("&fit candidates = '"//trim(deck%candidates(i))// &
                                    "' is not a known effect, expected one of: "// &
                                    'axial_coupling, material_cubic, elbow_flex, root_flex')
                return
            end if
        end do
        if (.not. (alpha > 0.0_dp .and. alpha < 1.0_dp)) then
            call fail('&fit alpha = '//fmt_g(alpha)//', expected a significance level in (0, 1)')
            return
        end if
        if (max_iter < 1) then
            call fail('&fit max_iter = '//fmt_int(max_iter)//', expected at least 1')
            return
        end if
        deck%alpha = alpha
        deck%max_iter = max_iter

    contains

        subroutine fail(text)
            character(len=*), intent(in) :: text
            call set_status(stat, ERR_DECK, trim(path), text)
        end subroutine fail

        subroutine clear_and_fail(text)
            character(len=*), intent(in) :: text
            stat%code = STATUS_OK
            call fail(text)
        end subroutine clear_and_fail
    end subroutine read_fit_groups

    !> Reject groups whose names beamid does not know (a misspelt group would
    !! otherwise be skipped silently by the namelist reader).
    !! `present` lists the groups found, each as '&name ' once; a group
    !! other than the REPEATABLE ones may appear only once.
    subroutine check_groups(unit, path, present, stat)
        integer, intent(in) :: unit
        character(len=*), intent(in) :: path
        character(len=:), allocatable, intent(out) :: present
        type(status_t), intent(inout) :: stat
        character(len=1024) :: line
        character(len=:), allocatable :: name, seen
        integer :: ios, lineno, k, e, n, at
        present = ''
        seen = ' '
        lineno = 0
        do
            read (unit, '(a)', iostat=ios) line
            if (ios /= 0) exit
            lineno = lineno + 1
            line = adjustl(line)
            if (line(1:1) /= '&') cycle
            e = scan(line(2:), ' /,!') 
            if (e == 0) e = len_trim(line)
            name = lower(line(2:e))
            k = index(KNOWN_GROUPS, ' '//name//' ')
            if (len(name) == 0 .or. name == 'end') cycle
            if (k == 0) then
                call set_status(stat, ERR_DECK, trim(path), 'line '//fmt_int(lineno)// &
                                ': unknown group &'//name//', expected one of:'// &
                                KNOWN_GROUPS(:len_trim(KNOWN_GROUPS)))
                return
            end if
            ! the namelist reader skips the rest of a line after a group's '/'
            k = index(line, '/')
            if (k > 0) then
                if (index(line(k:), '&') > 0) then
                    call set_status(stat, ERR_DECK, trim(path), 'line '//fmt_int(lineno)// &
                                    ': one group per line (a second group follows '// &
                                    '&'//name//' on this line)')
                    return
                end if
            end if
            seen = seen//name//' '
            if (index(present, '&'//name//' ') == 0) present = present//'&'//name//' '
        end do
        ! repeated groups (the namelist reader would silently take the first)
        k = 1
        do while (k < len(present))
            e = index(present(k + 1:), ' ')
            name = present(k + 1:k + e - 1)
            k = k + e + 1
            if (index(REPEATABLE, ' '//name//' ') > 0) cycle
            n = 0
            at = 1
            do
                e = index(seen(at:), ' '//name//' ')
                if (e == 0) exit
                n = n + 1
                at = at + e
            end do
            if (n > 1) then
                call set_status(stat, ERR_DECK, trim(path), 'group &'//name//' appears '// &
                                fmt_int(n)//' times')
                return
            end if
        end do
    end subroutine check_groups
end module beamid_deck
