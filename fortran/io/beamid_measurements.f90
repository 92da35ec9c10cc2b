!> Measurement tables for the estimation decks (docs/decks.md, "Estimation decks").
!!
!! A table is a CSV file: `#` comments and blank lines, the header
!! `experiment,t,quantity,value,sigma`, then one row per measurement. Every
!! row is validated with the rules and messages of the Python reader
!! (`pyfront/beamid/measurements.py`), so both name the same file, line and
!! field: wrong field count, empty experiment, non-numeric or non-finite t,
!! value or sigma, unknown quantity, sigma <= 0 (an empty sigma is not given:
!! NaN, estimated by the fit or refused there), t < 0, duplicate rows, and
!! (check_experiments) an experiment the deck does not define.
!!
!! Library code: no printing, no STOP; errors come back in a status_t with
!! ERR_INPUT (bad content) or ERR_IO (file cannot be opened or read).
module beamid_measurements
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan, ieee_value, &
                                             ieee_quiet_nan
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, STATUS_OK, ERR_INPUT, ERR_IO, ERR_SIZE, &
                             MAX_BYTES, fmt_int, fmt_bytes, set_alloc_error, lower
    use beamid_observations, only: observation_t, parse_observation, obs_label, kinds_list, &
                                   same_observation, observation_why_not, FAM_STATIC, &
                                   FAM_RELEASE, FAM_MODAL, why_detail, WHY_OK, WHY_WIRE, WHY_MOTOR, WHY_FAMILY, &
                                   K_MOTOR_TORQUE, K_WIRE_FORCE
    implicit none
    private

    public :: measurements_t, read_measurements, check_experiments, check_static_rows, fmt_g
    public :: read_channel_file, TIME_HEADERS, sensor_t

    character(len=*), parameter :: HEADER = 'experiment,t,quantity,value,sigma'
    !> Accepted names of a logger file's time column (its first column).
    character(len=*), parameter :: TIME_HEADERS(4) = [character(len=6) :: 't', 'time', &
                                                      'time_s', 't_s']

    !> A sensor of a logger file: its channel name, the observation it makes
    !! and the sigma of one reading (<= 0: none of its own).
    type :: sensor_t
        character(len=:), allocatable :: name, observation
        real(dp) :: sigma = 0.0_dp
    end type sensor_t

    !> A validated table, one entry per row in file order.
    type :: measurements_t
        character(len=:), allocatable :: source         !< file name (for messages)
        character(len=:), allocatable :: experiment(:)  !< experiment name of each row
        real(dp), allocatable :: t(:)                   !< time (0 for static experiments)
        integer, allocatable :: quantity(:)             !< observation kind code (beamid_observations)
        type(observation_t), allocatable :: obs(:)      !< observation of each row (kind, locus)
        real(dp), allocatable :: value(:)
        real(dp), allocatable :: sigma(:)               !< standard deviation, > 0
        integer, allocatable :: line(:)                 !< source line of each row
    end type measurements_t

contains

    !> Read and validate a measurement CSV file.
    subroutine read_measurements(path, data, stat)
        character(len=*), intent(in) :: path
        type(measurements_t), intent(out) :: data
        type(status_t), intent(inout) :: stat
        character(len=:), allocatable :: lines(:)

        data%source = path
        call read_lines(path, lines, stat)
        if (stat%code /= STATUS_OK) return
        call parse_rows(path, lines, data, stat)
        if (stat%code /= STATUS_OK) return
        call check_row_values(path, data, stat)
    end subroutine read_measurements

    !> Read a data logger's wide CSV (a time column `t` or `time`, then one
    !! column per channel) into the rows of `experiment`, as the Python
    !! front's beamid.read_channels does, with its messages: a channel's
    !! header is a sensor's name (sensors(k)%name: it measures
    !! sensors(k)%observation with sigma sensors(k)%sigma) or an
    !! observation name itself; a channel without a sigma of its own takes
    !! `sigma` (<= 0: none, an error). An empty field is a channel not
    !! sampled at that time. Rows in file order, per line the channels in
    !! column order.
    subroutine read_channel_file(path, experiment, sensors, sigma, data, stat)
        character(len=*), intent(in) :: path, experiment
        type(sensor_t), intent(in) :: sensors(:)
        real(dp), intent(in) :: sigma
        type(measurements_t), intent(out) :: data
        type(status_t), intent(inout) :: stat
        character(len=:), allocatable :: lines(:), line, hw, name, field, why, known
        type(observation_t), allocatable :: chan_obs(:)
        real(dp), allocatable :: chan_sig(:)
        integer, allocatable :: comma(:), hcomma(:)
        character(len=:), allocatable :: header
        integer :: i, k, c, nh, nrow, hline, ierr
        real(dp) :: t, v
        data%source = path
        call read_lines(path, lines, stat)
        if (stat%code /= STATUS_OK) return
        hline = 0
        do i = 1, size(lines)
            line = clean(lines(i))
            if (len(line) == 0) cycle
            hline = i
            exit
        end do
        if (hline == 0) then
            call set_status(stat, ERR_INPUT, path, 'no header line (a time column, then one '// &
                            'column per channel)')
            return
        end if
        header = line
        call split(header, hcomma)
        nh = size(hcomma) + 1
        hw = path//', line '//fmt_int(hline)
        if (.not. any(TIME_HEADERS == lower(field_of(header, hcomma, 1)))) then
            call set_status(stat, ERR_INPUT, hw, 'the first column is '// &
                            quote(field_of(header, hcomma, 1))//', expected the time (t or time)')
            return
        end if
        if (nh < 2) then
            call set_status(stat, ERR_INPUT, hw, 'no channel column after the time')
            return
        end if
        allocate (chan_obs(nh - 1), chan_sig(nh - 1))
        do c = 2, nh
            name = field_of(header, hcomma, c)
            k = 0
            do i = 1, size(sensors)
                if (sensors(i)%name == name) k = i
            end do
            if (k > 0) then
                call parse_observation(sensors(k)%observation, chan_obs(c - 1), why)
                if (len(why) > 0) then
                    call set_status(stat, ERR_INPUT, hw, 'sensor '//quote(name)// &
                                    ': observation = '//quote(sensors(k)%observation)//': '//why)
                    return
                end if
                chan_sig(c - 1) = sensors(k)%sigma
            else
                call parse_observation(name, chan_obs(c - 1), why)
                if (len(why) > 0 .or. len(name) == 0) then
                    known = ''
                    do k = 1, size(sensors)
                        if (k > 1) known = known//', '
                        known = known//sensors(k)%name
                    end do
                    if (size(sensors) == 0) known = 'none'
                    call set_status(stat, ERR_INPUT, hw, 'channel header '//quote(name)// &
                                    ' matches no sensor (sensors: '//known//') and is no '// &
                                    'observation (kind or kind@beam:s)')
                    return
                end if
                chan_sig(c - 1) = 0.0_dp
            end if
            if (.not. chan_sig(c - 1) > 0.0_dp) chan_sig(c - 1) = sigma
            if (.not. chan_sig(c - 1) > 0.0_dp) then
                call set_status(stat, ERR_INPUT, hw, 'channel '//quote(name)//' has no sigma: '// &
                                'give sigma= or a Sensor with one')
                return
            end if
        end do
        nrow = (nh - 1)*(size(lines) - hline)
        allocate (character(len=max(1, len_trim(experiment))) :: data%experiment(nrow))
        allocate (data%obs(nrow))
        allocate (data%t(nrow), data%quantity(nrow), data%value(nrow), data%sigma(nrow), &
                  data%line(nrow), stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(stat, 'read_channels', 'the rows of '//path, &
                                 40.0_dp*real(nrow, dp))
            return
        end if
        nrow = 0
        do i = hline + 1, size(lines)
            line = clean(lines(i))
            if (len(line) == 0) cycle
            call split(line, comma)
            if (size(comma) + 1 /= nh) then
                call set_status(stat, ERR_INPUT, path//', line '//fmt_int(i), 'expected '// &
                                fmt_int(nh)//' fields ('//header//'), got '// &
                                fmt_int(size(comma) + 1))
                return
            end if
            field = field_of(line, comma, 1)
            call parse_number(field, path//', line '//fmt_int(i), &
                              field_of(header, hcomma, 1), t, stat)
            if (stat%code /= STATUS_OK) return
            do c = 2, nh
                field = field_of(line, comma, c)
                if (len(field) == 0) cycle          ! a channel not sampled at this time
                call parse_number(field, path//', line '//fmt_int(i), &
                                  field_of(header, hcomma, c), v, stat)
                if (stat%code /= STATUS_OK) return
                nrow = nrow + 1
                data%experiment(nrow) = experiment
                data%t(nrow) = t
                data%obs(nrow) = chan_obs(c - 1)
                data%quantity(nrow) = chan_obs(c - 1)%kind
                data%value(nrow) = v
                data%sigma(nrow) = chan_sig(c - 1)
                data%line(nrow) = i
            end do
        end do
        data%experiment = data%experiment(:nrow)
        data%t = data%t(:nrow)
        data%quantity = data%quantity(:nrow)
        data%obs = data%obs(:nrow)
        data%value = data%value(:nrow)
        data%sigma = data%sigma(:nrow)
        data%line = data%line(:nrow)
        call check_row_values(path, data, stat)
    end subroutine read_channel_file

    !> Every line of the file `path`, as long as its longest (ERR_IO when it
    !! cannot be opened or read, ERR_SIZE when it would not fit in MAX_BYTES).
    subroutine read_lines(path, lines, stat)
        character(len=*), intent(in) :: path
        character(len=:), allocatable, intent(out) :: lines(:)
        type(status_t), intent(inout) :: stat
        character(len=:), allocatable :: line
        integer :: unit, ios, nlines, maxlen, i, ierr
        character(len=512) :: msg
        logical :: exists

        inquire (file=path, exist=exists)
        if (.not. exists) then
            call set_status(stat, ERR_IO, 'cannot open measurement file '//path, 'no such file')
            return
        end if
        open (newunit=unit, file=path, status='old', action='read', iostat=ios, iomsg=msg)
        if (ios /= 0) then
            call set_status(stat, ERR_IO, 'cannot read measurement file '//path, trim(msg))
            return
        end if
        ! two passes: count the lines and their longest length, then keep them
        nlines = 0
        maxlen = 1
        do
            call read_line(unit, line, ios)
            if (ios /= 0) exit
            nlines = nlines + 1
            maxlen = max(maxlen, len(line))
        end do
        if (real(nlines, dp)*real(maxlen, dp) > MAX_BYTES) then
            close (unit)
            call set_status(stat, ERR_SIZE, 'cannot read measurement file '//path, &
                            fmt_int(nlines)//' lines of up to '//fmt_int(maxlen)// &
                            ' characters need more than '//fmt_bytes(MAX_BYTES)//' of memory')
            return
        end if
        allocate (character(len=maxlen) :: lines(nlines), stat=ierr)
        if (ierr /= 0) then
            close (unit)
            call set_alloc_error(stat, 'read_measurements', 'the lines of '//path, &
                                 real(nlines, dp)*real(maxlen, dp))
            return
        end if
        rewind (unit)
        do i = 1, nlines
            call read_line(unit, line, ios)
            if (ios /= 0) exit
            lines(i) = line
        end do
        close (unit)
        if (ios > 0) call set_status(stat, ERR_IO, 'cannot read measurement file '//path, &
                                     'read error')
    end subroutine read_lines

    !> Pass 1: the syntax of every line (as read_measurements in Python): the
    !! header, then rows of 5 fields; data holds the rows, in file order.
    subroutine parse_rows(path, lines, data, stat)
        character(len=*), intent(in) :: path, lines(:)
        type(measurements_t), intent(inout) :: data
        type(status_t), intent(inout) :: stat
        character(len=:), allocatable :: line, where
        integer, allocatable :: comma(:)
        integer :: nlines, i, nrow, nf, ierr
        logical :: header_seen

        nlines = size(lines)
        allocate (character(len=len(lines)) :: data%experiment(nlines))
        allocate (data%obs(nlines))
        allocate (data%t(nlines), data%quantity(nlines), data%value(nlines), &
                  data%sigma(nlines), data%line(nlines), stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(stat, 'read_measurements', 'the rows of '//path, &
                                 40.0_dp*real(nlines, dp))
            return
        end if
        header_seen = .false.
        nrow = 0
        do i = 1, nlines
            line = clean(lines(i))
            if (len(line) == 0) cycle
            where = path//', line '//fmt_int(i)
            call split(line, comma)
            nf = size(comma) + 1
            if (.not. header_seen) then
                if (nf /= 5 .or. .not. header_matches(line, comma)) then
                    call set_status(stat, ERR_INPUT, where, 'expected the header '//HEADER// &
                                    ', got '//quote(line))
                    return
                end if
                header_seen = .true.
                cycle
            end if
            if (nf /= 5) then
                call set_status(stat, ERR_INPUT, where, 'expected 5 fields ('//HEADER// &
                                '), got '//fmt_int(nf))
                return
            end if
            nrow = nrow + 1
            data%line(nrow) = i
            call parse_row(line, comma, where, data, nrow, stat)
            if (stat%code /= STATUS_OK) return
        end do
        if (.not. header_seen) then
            call set_status(stat, ERR_INPUT, path, 'no header line '//HEADER//' found')
        else if (nrow == 0) then
            call set_status(stat, ERR_INPUT, path, 'no measurement rows after the header')
        end if
        if (stat%code /= STATUS_OK) return
        data%experiment = data%experiment(:nrow)
        data%t = data%t(:nrow)
        data%quantity = data%quantity(:nrow)
        data%obs = data%obs(:nrow)
        data%value = data%value(:nrow)
        data%sigma = data%sigma(:nrow)
        data%line = data%line(:nrow)
    end subroutine parse_rows

    !> The fields of one row (a line split at `comma` into 5 fields) into
    !! row `irow` of data.
    subroutine parse_row(line, comma, where, data, irow, stat)
        character(len=*), intent(in) :: line, where
        integer, intent(in) :: comma(:), irow
        type(measurements_t), intent(inout) :: data
        type(status_t), intent(inout) :: stat
        character(len=:), allocatable :: field, why
        field = field_of(line, comma, 1)
        if (len(field) == 0) then
            call set_status(stat, ERR_INPUT, where, 'field experiment is empty')
            return
        end if
        data%experiment(irow) = field
        call parse_number(field_of(line, comma, 2), where, 't', data%t(irow), stat)
        if (stat%code /= STATUS_OK) return
        field = field_of(line, comma, 3)
        call parse_observation(field, data%obs(irow), why)
        data%quantity(irow) = data%obs(irow)%kind
        if (data%obs(irow)%kind == 0 .or. len(field) == 0) then
            call set_status(stat, ERR_INPUT, where, 'field quantity = '//quote(field)// &
                            ', expected one of '//kinds_list())
            return
        else if (len(why) > 0) then
            call set_status(stat, ERR_INPUT, where, 'field quantity = '//quote(field)//': '//why)
            return
        end if
        call parse_number(field_of(line, comma, 4), where, 'value', data%value(irow), stat)
        if (stat%code /= STATUS_OK) return
        ! an empty sigma is not given (NaN): the fit estimates it (estimate_sigma)
        ! or refuses the row (beamid_inverse, check_sigma_given)
        field = field_of(line, comma, 5)
        if (len(trim(field)) == 0) then
            data%sigma(irow) = ieee_value(1.0_dp, ieee_quiet_nan)
            return
        end if
        call parse_number(field, where, 'sigma', data%sigma(irow), stat)
    end subroutine parse_row

    !> Pass 2: the values of every row (as Measurements.__post_init__):
    !! sigma > 0, t >= 0, no row given twice.
    pure subroutine check_row_values(path, data, stat)
        character(len=*), intent(in) :: path
        type(measurements_t), intent(in) :: data
        type(status_t), intent(inout) :: stat
        character(len=:), allocatable :: where
        integer :: i, first
        do i = 1, size(data%t)
            where = path//', line '//fmt_int(data%line(i))
            if (.not. data%sigma(i) > 0.0_dp .and. .not. ieee_is_nan(data%sigma(i))) then
                call set_status(stat, ERR_INPUT, where, 'field sigma = '//fmt_g(data%sigma(i))// &
                                ', expected sigma > 0 (the standard deviation of the row)')
                return
            end if
            if (data%t(i) < 0.0_dp) then
                call set_status(stat, ERR_INPUT, where, 'field t = '//fmt_g(data%t(i))// &
                                ', expected t >= 0')
                return
            end if
            first = findloc(data%experiment(:i - 1) == data%experiment(i) .and. data%t(:i - 1) &
                            == data%t(i) .and. same_observation(data%obs(:i - 1), data%obs(i)), &
                            .true., 1)
            if (first > 0) then
                call set_status(stat, ERR_INPUT, where, 'duplicate row: experiment '// &
                                quote(trim(data%experiment(i)))//', t = '//fmt_g(data%t(i))// &
                                ', quantity '//quote(obs_label(data%obs(i)))// &
                                ' already given ('//path//', line '// &
                                fmt_int(data%line(first))//')')
                return
            end if
        end do
    end subroutine check_row_values

    !> Error for a row whose experiment is not among `names`.
    pure subroutine check_experiments(data, names, stat)
        type(measurements_t), intent(in) :: data
        character(len=*), intent(in) :: names(:)
        type(status_t), intent(inout) :: stat
        integer :: i, k
        character(len=:), allocatable :: known
        do i = 1, size(data%experiment)
            if (any(names == data%experiment(i))) cycle
            known = ''
            do k = 1, size(names)
                if (k > 1) known = known//', '
                known = known//trim(names(k))
            end do
            if (size(names) == 0) known = 'none'
            call set_status(stat, ERR_INPUT, data%source//', line '//fmt_int(data%line(i)), &
                            'field experiment = '//quote(trim(data%experiment(i)))// &
                            ' is not defined (experiments: '//known//')')
            return
        end do
    end subroutine check_experiments

    !> Rows of static experiments: t must be 0, and wire_force needs a wire
    !! (the checks of beamid.estimation.build_problem). `row_exp` gives each
    !! row's experiment index into names/is_wire.
    pure subroutine check_static_rows(data, names, is_wire, row_exp, stat, is_release, has_motor, &
                                      lengths, is_modal)
        type(measurements_t), intent(in) :: data
        character(len=*), intent(in) :: names(:)
        logical, intent(in) :: is_wire(:)
        integer, allocatable, intent(out) :: row_exp(:)
        type(status_t), intent(inout) :: stat
        !> release experiments (issue 13): any t >= 0, no wire_force, and
        !! motor_torque only with a motor (has_motor)
        logical, intent(in), optional :: is_release(:), has_motor(:)
        !> the model's beam lengths: stations are checked against them
        real(dp), intent(in), optional :: lengths(:)
        !> modal experiments (issue 27): t = 0, the modal kinds only
        logical, intent(in), optional :: is_modal(:)
        real(dp), allocatable :: len_b(:)
        integer :: i, e, reason, nb, fam
        logical :: release, motor, wire, modal
        character(len=:), allocatable :: where, x, why, q, detail
        allocate (row_exp(size(data%experiment)), source=0)
        call check_experiments(data, names, stat)
        if (stat%code /= STATUS_OK) return
        do i = 1, size(data%experiment)
            where = data%source//', line '//fmt_int(data%line(i))
            do e = 1, size(names)
                if (names(e) == data%experiment(i)) row_exp(i) = e
            end do
            release = .false.
            if (present(is_release)) release = is_release(row_exp(i))
            x = ', but experiment '//quote(trim(data%experiment(i)))
            why = ''
            q = "field quantity = "//quote(obs_label(data%obs(i)))
            motor = .false.
            wire = .false.
            if (release .and. present(has_motor)) motor = has_motor(row_exp(i))
            if (.not. release) wire = is_wire(row_exp(i))
            nb = huge(1)
            allocate (len_b(0))
            if (present(lengths)) then
                if (size(lengths) > 0) then
                    nb = size(lengths)
                    len_b = lengths
                end if
            end if
            modal = .false.
            if (present(is_modal)) modal = is_modal(row_exp(i))
            fam = merge(FAM_RELEASE, FAM_STATIC, release)
            if (modal) fam = FAM_MODAL
            reason = observation_why_not(data%obs(i), fam, wire, motor, nb, len_b)
            detail = why_detail(data%obs(i), reason, fam, nb, len_b)
            deallocate (len_b)
            if (modal) then
                if (reason /= WHY_OK) then
                    why = q//x//' is a modal test ('//detail//')'
                else if (data%t(i) /= 0.0_dp) then
                    why = 'field t = '//fmt_g(data%t(i))//', expected 0 for the modal '// &
                          'experiment '//quote(trim(data%experiment(i)))
                end if
            else if (.not. release .and. data%t(i) /= 0.0_dp .and. &
                (reason == WHY_OK .or. reason == WHY_WIRE)) then
                why = 'field t = '//fmt_g(data%t(i))//', expected 0 for the static experiment '// &
                      quote(trim(data%experiment(i)))
            else if (reason == WHY_FAMILY .and. data%obs(i)%kind == K_MOTOR_TORQUE) then
                why = q//x//' is static (no motor)'
            else if (reason == WHY_FAMILY .and. data%obs(i)%kind == K_WIRE_FORCE) then
                why = q//x//' is a release (no wire)'
            else if (reason == WHY_FAMILY) then
                why = q//x//' is '//trim(merge('a release', 'static   ', release))//' ('//detail//')'
            else if (reason == WHY_MOTOR) then
                why = q//x//' has no motor (motor_gain = 0)'
            else if (reason == WHY_WIRE) then
                why = q//x//' has no wire'
            else if (reason /= WHY_OK) then
                why = q//': '//detail
            end if
            if (len(why) > 0) then
                call set_status(stat, ERR_INPUT, where, why)
                return
            end if
        end do
    end subroutine check_static_rows

    !> Python's format(x, 'g'): six significant digits, trailing zeros dropped.
    pure function fmt_g(x) result(text)
        real(dp), intent(in) :: x
        character(len=:), allocatable :: text
        character(len=40) :: buffer
        integer :: e, epos
        if (ieee_is_nan(x)) then
            text = 'nan'
            return
        else if (.not. ieee_is_finite(x)) then
            text = merge('inf ', '-inf', x > 0.0_dp)
            text = trim(text)
            return
        else if (x == 0.0_dp) then
            text = merge('0 ', '-0', sign(1.0_dp, x) > 0.0_dp)
            text = trim(text)
            return
        end if
        write (buffer, '(es14.5e3)') x
        epos = index(buffer, 'E')
        read (buffer(epos + 1:), *) e
        if (e >= -4 .and. e < 6) then
            write (buffer, '(f0.'//fmt_int(5 - e)//')') x
            text = strip_zeros(trim(adjustl(buffer)))
            if (text(1:1) == '.') text = '0'//text
            if (text(1:2) == '-.') text = '-0'//text(2:)
        else
            text = strip_zeros(trim(adjustl(buffer(:epos - 1))))
            if (abs(e) < 10) then
                text = text//'e'//merge('+', '-', e >= 0)//'0'//fmt_int(abs(e))
            else
                text = text//'e'//merge('+', '-', e >= 0)//fmt_int(abs(e))
            end if
        end if
    contains
        pure function strip_zeros(s) result(r)
            character(len=*), intent(in) :: s
            character(len=:), allocatable :: r
            integer :: n
            r = s
            if (index(r, '.') == 0) return
            n = len(r)
            do while (r(n:n) == '0')
                n = n - 1
            end do
            if (r(n:n) == '.') n = n - 1
            r = r(:n)
        end function strip_zeros
    end function fmt_g

    ! ------------------------------------------------------------------ helpers

    !> One line of any length (ios < 0 at the end of the file).
    subroutine read_line(unit, line, ios)
        integer, intent(in) :: unit
        character(len=:), allocatable, intent(out) :: line
        integer, intent(out) :: ios
        character(len=256) :: chunk
        integer :: nread
        line = ''
        do
            read (unit, '(a)', advance='no', iostat=ios, size=nread) chunk
            line = line//chunk(:nread)
            if (ios /= 0) exit
        end do
        if (is_iostat_eor(ios)) ios = 0
    end subroutine read_line

    !> Text before any `#`, tabs and carriage returns as blanks, trimmed.
    pure function clean(raw) result(line)
        character(len=*), intent(in) :: raw
        character(len=:), allocatable :: line
        integer :: i, h
        line = raw
        h = index(line, '#')
        if (h > 0) line = line(:h - 1)
        do i = 1, len(line)
            if (line(i:i) == achar(9) .or. line(i:i) == achar(13)) line(i:i) = ' '
        end do
        line = trim(adjustl(line))
    end function clean

    !> Positions of the commas of a line.
    pure subroutine split(line, comma)
        character(len=*), intent(in) :: line
        integer, allocatable, intent(out) :: comma(:)
        integer :: i
        allocate (comma(0))
        do i = 1, len(line)
            if (line(i:i) == ',') comma = [comma, i]
        end do
    end subroutine split

    !> Field k (1-based) of a line split at `comma`, blanks stripped.
    pure function field_of(line, comma, k) result(field)
        character(len=*), intent(in) :: line
        integer, intent(in) :: comma(:), k
        character(len=:), allocatable :: field
        integer :: a, b
        a = 1
        if (k > 1) a = comma(k - 1) + 1
        b = len(line)
        if (k <= size(comma)) b = comma(k) - 1
        field = trim(adjustl(line(a:b)))
    end function field_of

    pure logical function header_matches(line, comma)
        character(len=*), intent(in) :: line
        integer, intent(in) :: comma(:)
        character(len=*), parameter :: names(5) = [character(len=10) :: 'experiment', 't', &
                                                   'quantity', 'value', 'sigma']
        integer :: k
        header_matches = .true.
        do k = 1, 5
            if (lower(field_of(line, comma, k)) /= trim(names(k))) header_matches = .false.
        end do
    end function header_matches

    !> A decimal number as Python's float() reads it (sign, digits with an
    !! optional point, optional exponent); inf and nan are numbers but not
    !! finite ones.
    subroutine parse_number(text, where, name, value, stat)
        character(len=*), intent(in) :: text, where, name
        real(dp), intent(out) :: value
        type(status_t), intent(inout) :: stat
        integer :: ios
        character(len=:), allocatable :: body
        value = 0.0_dp
        body = lower(text)
        if (len(body) > 0) then
            if (body(1:1) == '+' .or. body(1:1) == '-') body = body(2:)
        end if
        if (body == 'inf' .or. body == 'infinity' .or. body == 'nan') then
            call set_status(stat, ERR_INPUT, where, 'field '//name//' = '//quote(text)// &
                            ', expected a finite number')
            return
        end if
        if (.not. decimal_syntax(text)) then
            call set_status(stat, ERR_INPUT, where, 'field '//name//' = '//quote(text)// &
                            ', expected a number')
            return
        end if
        read (text, *, iostat=ios) value
        if (ios /= 0 .or. .not. ieee_is_finite(value)) then
            call set_status(stat, ERR_INPUT, where, 'field '//name//' = '//quote(text)// &
                            ', expected a finite number')
        end if
    end subroutine parse_number

    !> [+-] digits [. digits] [(e|E) [+-] digits], with at least one mantissa digit.
    pure logical function decimal_syntax(text)
        character(len=*), intent(in) :: text
        integer :: i, n, digits
        decimal_syntax = .false.
        n = len(text)
        i = 1
        if (n == 0) return
        if (text(1:1) == '+' .or. text(1:1) == '-') i = 2
        digits = 0
        do while (i <= n)
            if (.not. is_digit(text(i:i))) exit
            digits = digits + 1
            i = i + 1
        end do
        if (i <= n) then
            if (text(i:i) == '.') then
                i = i + 1
                do while (i <= n)
                    if (.not. is_digit(text(i:i))) exit
                    digits = digits + 1
                    i = i + 1
                end do
            end if
        end if
        if (digits == 0) return
        if (i <= n) then
            if (text(i:i) /= 'e' .and. text(i:i) /= 'E') return
            i = i + 1
            if (i <= n) then
                if (text(i:i) == '+' .or. text(i:i) == '-') i = i + 1
            end if
            if (i > n) return
            do while (i <= n)
                if (.not. is_digit(text(i:i))) return
                i = i + 1
            end do
        end if
        decimal_syntax = .true.
    end function decimal_syntax

    pure logical function is_digit(c)
        character, intent(in) :: c
        is_digit = c >= '0' .and. c <= '9'
    end function is_digit

    !> Python's repr of a plain string: 'text'.
    pure function quote(text) result(q)
        character(len=*), intent(in) :: text
        character(len=:), allocatable :: q
        q = "'"//text//"'"
    end function quote

end module beamid_measurements
