!> f2py-facing API of the deck and measurement readers and of the task
!! runners: Python reads decks and measurement CSVs and runs decks through
!! the same Fortran as beamid-batch (docs/decks.md).
!!
!! A deck is read twice: api_deck_sizes validates it and returns the array
!! sizes and the scalars, api_deck_arrays fills the arrays (no state is kept
!! between the calls). Messages: every problem, one per line.
!! Outputs of a failed call are zeros: f2py allocates output arrays zeroed and
!! declares output scalars = 0 (characters blank), so no entry zeroes them.
module beamid_api_deck
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, status_out, put_text, fmt_int, STATUS_OK, ERR_INPUT, &
                             exit_code, set_status
    use beamid_deck, only: deck_t, read_deck, deck_set_task
    use beamid_tasks, only: run_task, deck_experiments
    use beamid_measurements, only: measurements_t, read_measurements
    use beamid_observations, only: kind_label, NKIND, kind_table_text, observation_t, &
                                   parse_observation, obs_label, obs_groups
    implicit none
    private

    public :: api_deck_sizes, api_deck_arrays, api_run_deck, api_measurements_size, &
              api_measurements_read, api_exit_code, api_quantity_labels, &
              api_observation_table, api_observation_parse, api_deck_history_sizes, &
              api_deck_histories

    !> Length of the messages and texts exchanged here.
    integer, parameter :: TEXT_LEN = 65536

contains

    !> Exit code of a status code (beamid_status exit_code).
    subroutine api_exit_code(code, ecode)
        integer(c_int), intent(in) :: code
        integer(c_int), intent(out) :: ecode
        ecode = int(exit_code(int(code)), c_int)
    end subroutine api_exit_code

    !> All problems of a read, one per line, into message.
    subroutine put_errors(deck, stat, code, message)
        type(deck_t), intent(in) :: deck
        type(status_t), intent(in) :: stat
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        call status_out(stat, code, message)
        if (allocated(deck%errors)) then
            if (len(deck%errors) > 0) call put_text(deck%errors, message)
        end if
    end subroutine put_errors

    !> Read and validate a deck. sizes: nbeams, nparams, nwrt, nt (output
    !! times), nexp, nfree, nprior, ncand, ndata (measurement rows), has_load,
    !! shape_points, fe_elements_per_beam, fe_moment_form, fe_rotary_inertia,
    !! fe_point_masses, fe_steps, sim_elements_per_beam, sim_integrator,
    !! sim_friction, max_iter, load_kind. reals: load fx, fy, moment,
    !! wire_length, tol, fe_tol, sim_dt, sim_rtol, sim_atol, sim_motor_gain,
    !! sim_friction_velocity, alpha. text: task, output, data path, then the
    !! experiment names and the candidates, one per line, then the &published
    !! lines (deck_t%published), then for task identify one line per stage
    !! (deck_t%stage_text).
    subroutine api_deck_sizes(path, sizes, reals, text, code, message)
        character(len=*), intent(in) :: path
        integer(c_int), intent(out) :: sizes(21)
        real(c_double), intent(out) :: reals(12)
        character(len=65536), intent(out) :: text
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        type(deck_t) :: d
        type(status_t) :: stat
        character(len=:), allocatable :: t
        integer :: i
        text = ''
        call read_deck(trim(path), d, stat)
        call put_errors(d, stat, code, message)
        if (stat%code /= STATUS_OK) return
        sizes = int([d%nbeams, size(d%params), nsize_i(d%wrt), nsize_r(d%sim_t_out), &
                     nexp(d), nsize_i(d%free), nsize_i(d%prior_index), ncand(d), &
                     nsize_r(d%data%value), merge(1, 0, d%has_load), d%shape_points, &
                     d%fe_elements_per_beam, d%fe_moment_form, merge(1, 0, d%fe_rotary_inertia), &
                     merge(1, 0, d%fe_point_masses), d%fe_steps, d%sim_elements_per_beam, &
                     d%sim_integrator, d%sim_friction, d%max_iter, d%load%kind], c_int)
        reals = [d%load%fx, d%load%fy, d%load%moment, d%load%wire_length, d%tol, d%fe_tol, &
                 d%sim_dt, d%sim_rtol, d%sim_atol, d%sim_motor_gain, d%sim_friction_velocity, &
                 d%alpha]
        t = d%task//new_line('a')//d%output//new_line('a')
        if (allocated(d%data_path)) t = t//d%data_path
        t = t//new_line('a')
        do i = 1, nexp(d)
            t = t//trim(d%exp_names(i))//new_line('a')
        end do
        do i = 1, ncand(d)
            t = t//trim(d%candidates(i))//new_line('a')
        end do
        t = t//d%published
        if (allocated(d%stage_text)) t = t//d%stage_text   ! task identify: 'S' lines
        if (len(t) > TEXT_LEN) then
            code = int(ERR_INPUT, c_int)
            message = trim(path)//': the names of the deck are too long (over '// &
                      fmt_int(TEXT_LEN)//' characters)'
            return
        end if
        text = t
    contains
        pure integer function nsize_i(a)
            integer, allocatable, intent(in) :: a(:)
            nsize_i = 0
            if (allocated(a)) nsize_i = size(a)
        end function nsize_i
        pure integer function nsize_r(a)
            real(dp), allocatable, intent(in) :: a(:)
            nsize_r = 0
            if (allocated(a)) nsize_r = size(a)
        end function nsize_r
    end subroutine api_deck_sizes

    !> The sizes of a deck's &history groups (beamid_deck_history): nh
    !! histories, ntab table rows (api_deck_histories returns them).
    subroutine api_deck_history_sizes(path, nh, ntab, code, message)
        character(len=*), intent(in) :: path
        integer(c_int), intent(out) :: nh, ntab
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        type(deck_t) :: d
        type(status_t) :: stat
        nh = 0
        ntab = 0
        call read_deck(trim(path), d, stat)
        call put_errors(d, stat, code, message)
        if (stat%code /= STATUS_OK) return
        if (allocated(d%hist%spec)) nh = int(size(d%hist%spec, 2), c_int)
        if (allocated(d%hist%tab)) ntab = int(size(d%hist%tab, 2), c_int)
    end subroutine api_deck_history_sizes

    !> A deck's &history groups: a column [experiment (1-based; a simulate
    !! deck's: 1), beamid_loads' 9 values] per history and the table rows
    !! (t, value) they refer to (sizes from api_deck_history_sizes).
    subroutine api_deck_histories(path, nh, ntab, spec, tab, code, message)
        character(len=*), intent(in) :: path
        integer(c_int), intent(in) :: nh, ntab
        real(c_double), intent(out) :: spec(10, nh), tab(2, ntab)
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        type(deck_t) :: d
        type(status_t) :: stat
        spec = 0.0_c_double
        tab = 0.0_c_double
        call read_deck(trim(path), d, stat)
        call put_errors(d, stat, code, message)
        if (stat%code /= STATUS_OK) return
        if (.not. allocated(d%hist%spec)) return
        if (size(d%hist%spec, 2) /= nh .or. size(d%hist%tab, 2) /= ntab) then
            code = int(ERR_INPUT, c_int)
            message = trim(path)//': the deck has '//fmt_int(size(d%hist%spec, 2))// &
                      ' histories and '//fmt_int(size(d%hist%tab, 2))//' table rows, asked '// &
                      fmt_int(int(nh))//' and '//fmt_int(int(ntab))
            return
        end if
        spec = real(d%hist%spec, c_double)
        tab = real(d%hist%tab, c_double)
    end subroutine api_deck_histories

    pure integer function nexp(d)
        type(deck_t), intent(in) :: d
        nexp = 0
        if (allocated(d%experiments)) nexp = size(d%experiments)
    end function nexp

    pure integer function ncand(d)
        type(deck_t), intent(in) :: d
        ncand = 0
        if (allocated(d%candidates)) ncand = size(d%candidates)
    end function ncand

    !> The arrays of a deck (sizes from api_deck_sizes): parameters, wrt and
    !! free parameter indices (1-based), output times, experiments (kind 1
    !! tip, 2 wire, 3 release and 12 values in beamid_inverse's EV_* layout:
    !! fx, fy, moment, wire_length, ...; beamid_tasks deck_experiments), priors.
    subroutine api_deck_arrays(path, nparams, nwrt, nt, nexp_, nfree, nprior, params, wrt, &
                               t_out, exp_kind, exp_values, free_idx, prior_index, prior_mean, &
                               prior_sigma, code, message)
        character(len=*), intent(in) :: path
        integer(c_int), intent(in) :: nparams, nwrt, nt, nexp_, nfree, nprior
        real(c_double), intent(out) :: params(nparams), t_out(nt), exp_values(18, nexp_)
        real(c_double), intent(out) :: prior_mean(nprior), prior_sigma(nprior)
        integer(c_int), intent(out) :: wrt(nwrt), exp_kind(nexp_), free_idx(nfree)
        integer(c_int), intent(out) :: prior_index(nprior)
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        type(deck_t) :: d
        type(status_t) :: stat
        integer, allocatable :: kinds(:)
        real(dp), allocatable :: values(:, :)
        call read_deck(trim(path), d, stat)
        call put_errors(d, stat, code, message)
        if (stat%code /= STATUS_OK) return
        if (size(d%params) /= nparams .or. nexp(d) /= nexp_) then
            code = int(ERR_INPUT, c_int)
            message = trim(path)//': the deck changed between two reads'
            return
        end if
        params = d%params
        if (nwrt > 0) wrt = int(d%wrt(:nwrt), c_int)
        if (nt > 0) t_out = d%sim_t_out(:nt)
        if (nexp_ > 0) then
            call deck_experiments(d, kinds, values)
            exp_kind = int(kinds, c_int)
            exp_values = values
        end if
        if (nfree > 0) free_idx = int(d%free(:nfree), c_int)
        if (nprior > 0) then
            prior_index = int(d%prior_index(:nprior), c_int)
            prior_mean = d%prior_mean(:nprior)
            prior_sigma = d%prior_sigma(:nprior)
        end if
    end subroutine api_deck_arrays

    !> Read a deck and run its task as beamid-batch does (beamid_tasks): the
    !! files written, one per line, in `written`. A non-blank `task` replaces
    !! the deck's (`beamid fit|compare|diagnose|improve DECK`): an estimation
    !! task for an estimation deck only.
    subroutine api_run_deck(path, task, written, summary, code, message)
        character(len=*), intent(in) :: path, task
        character(len=65536), intent(out) :: written
        !> the summary line beamid-batch prints (run_task)
        character(len=4096), intent(out) :: summary
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        type(deck_t) :: d
        type(status_t) :: stat
        character(len=:), allocatable :: files, line
        written = ''
        summary = ''
        call read_deck(trim(path), d, stat)
        if (stat%code == STATUS_OK) call deck_set_task(d, task, stat)
        if (stat%code == STATUS_OK) then
            call run_task(d, files, stat, summary=line)
            if (stat%code == STATUS_OK) call put_text(files, written)
            if (stat%code == STATUS_OK) summary = line
        end if
        call put_errors(d, stat, code, message)
    end subroutine api_run_deck

    !> Rows of a measurement CSV (after validation) and the longest name.
    subroutine api_measurements_size(path, nrow, code, message)
        character(len=*), intent(in) :: path
        integer(c_int), intent(out) :: nrow, code
        character(len=65536), intent(out) :: message
        type(measurements_t) :: data
        type(status_t) :: stat
        call read_measurements(trim(path), data, stat)
        call status_out(stat, code, message)
        if (stat%code == STATUS_OK) nrow = int(size(data%value), c_int)
    end subroutine api_measurements_size

    !> The rows of a measurement CSV: t, value, sigma, source line, the
    !! index of each row's observation into `qnames` (the distinct
    !! observation names, one per line, first use order, as
    !! beamid_observations writes them), and the index of each row's
    !! experiment into `names` (the distinct experiment names, likewise).
    subroutine api_measurements_read(path, nrow, t, value, sigma, line, quantity, exp_index, &
                                     names, qnames, code, message)
        character(len=*), intent(in) :: path
        integer(c_int), intent(in) :: nrow
        real(c_double), intent(out) :: t(nrow), value(nrow), sigma(nrow)
        integer(c_int), intent(out) :: line(nrow), quantity(nrow), exp_index(nrow)
        character(len=65536), intent(out) :: names, qnames
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        type(measurements_t) :: data
        type(status_t) :: stat
        character(len=:), allocatable :: joined
        character(len=:), allocatable :: seen(:)
        integer :: i, j, k, n
        names = ''
        call read_measurements(trim(path), data, stat)
        call status_out(stat, code, message)
        if (stat%code /= STATUS_OK) return
        if (size(data%value) /= nrow) then
            code = int(ERR_INPUT, c_int)
            message = trim(path)//': the file changed between two reads'
            return
        end if
        t = data%t
        value = data%value
        sigma = data%sigma
        line = int(data%line, c_int)
        quantity = int(obs_groups(data%obs), c_int)
        qnames = ''
        joined = ''
        do i = 1, nrow
            if (quantity(i) /= i) cycle
            joined = joined//obs_label(data%obs(i))//new_line('a')
        end do
        ! renumber the groups 1, 2, ... in first-use order
        n = 0
        do i = 1, nrow
            if (quantity(i) == i) then
                n = n + 1
                quantity(i) = int(n, c_int)
            else
                quantity(i) = quantity(quantity(i))
            end if
        end do
        if (len(joined) > TEXT_LEN) then
            code = int(ERR_INPUT, c_int)
            message = trim(path)//': the observation names take over '//fmt_int(TEXT_LEN)// &
                      ' characters'
            return
        end if
        qnames = joined
        allocate (character(len=len(data%experiment)) :: seen(nrow))
        n = 0
        joined = ''
        do i = 1, nrow
            k = 0
            do j = 1, n
                if (seen(j) == data%experiment(i)) then
                    k = j
                    exit
                end if
            end do
            if (k == 0) then
                n = n + 1
                seen(n) = data%experiment(i)
                k = n
                joined = joined//trim(data%experiment(i))//new_line('a')
            end if
            exp_index(i) = int(k, c_int)
        end do
        if (len(joined) > TEXT_LEN) then
            code = int(ERR_INPUT, c_int)
            message = trim(path)//': the experiment names take over '//fmt_int(TEXT_LEN)// &
                      ' characters'
            return
        end if
        names = joined
    end subroutine api_measurements_read

    !> Names of the observation kinds 1..n (beamid_observations), one per line.
    subroutine api_quantity_labels(text)
        character(len=4096), intent(out) :: text
        character(len=:), allocatable :: joined
        integer :: q
        joined = ''
        do q = 1, NKIND
            joined = joined//kind_label(q)//new_line('a')
        end do
        text = joined
    end subroutine api_quantity_labels

    !> The observation table of beamid_observations, one kind per line:
    !! name;unit;families;locus;needs;sigma;probe_static;probe_release;twin;about.
    subroutine api_observation_table(text)
        character(len=16384), intent(out) :: text
        text = kind_table_text()
    end subroutine api_observation_table

    !> Parse an observation name (beamid_observations parse_observation):
    !! its kind code, beam and arc length s (a station), mode, and the
    !! canonical name; code ERR_INPUT with what is wrong.
    subroutine api_observation_parse(name, kind, beam, s, mode, label, code, message)
        character(len=*), intent(in) :: name
        integer(c_int), intent(out) :: kind, beam, mode
        real(c_double), intent(out) :: s
        character(len=256), intent(out) :: label
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(observation_t) :: o
        type(status_t) :: stat
        character(len=:), allocatable :: why
        call parse_observation(name, o, why)
        if (len(why) > 0) call set_status(stat, ERR_INPUT, 'observation', why)
        call status_out(stat, code, message)
        kind = int(o%kind, c_int)
        beam = int(o%beam, c_int)
        mode = int(o%mode, c_int)
        s = real(o%s, c_double)
        label = ''
        if (len(why) == 0) label = obs_label(o)
    end subroutine api_observation_parse
end module beamid_api_deck
