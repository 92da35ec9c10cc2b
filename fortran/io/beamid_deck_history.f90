!> Load histories in decks (issue 28): the repeatable group &history of
!! simulate and estimation decks (docs/loads.md, docs/decks.md).
!!
!!     &history
!!       experiment = 'hammer'     ! estimation decks: the release it acts on
!!       target = 'tip_fy'         ! tip_fx tip_fy tip_torque motor_open hub
!!       form = 'half_sine'        ! half_sine step chirp table spin_up
!!       amplitude = 20.0, duration = 0.01, start = 0.0
!!     /
!!
!! Forms and their fields: half_sine (amplitude = the peak, duration, start),
!! step (amplitude, start), chirp (amplitude, f0, f1 in Hz, duration, start),
!! table (rows t = ..., value = ... inline, or file = 'a.csv' with column =
!! 'name' and time = 't'; scale), spin_up (target 'hub': w_s in rad/s and T
!! in s). A hub table is the hub angle (rad). Every problem is an error
!! naming the deck's file, line and field (or the CSV file's line and
!! field): a table whose times do not increase, a history that starts after
!! the experiment's last time, a spin-up with T <= 0, ...
!!
!! The histories go to exp_histories_t (the estimation's own list beside
!! the experiments' specs: a column [experiment, beamid_loads'
!! LD_NSPEC values] each; a simulate deck's are experiment 1).
module beamid_deck_history
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use beamid_kinds, only: dp
    use beamid_status, only: fmt_int, fmt_real, lower
    use beamid_namelist, only: nml_file_t, nml_group_t, nml_count, nml_find, nml_check_keys, &
                               nml_real, nml_reals, nml_str, nml_given, add_error, nml_where
    use beamid_loads, only: HIST_TABLE, HIST_HALF_SINE, HIST_STEP, HIST_CHIRP, HIST_SPIN_UP, &
                            TARGET_HUB, LD_NSPEC, TARGET_NAMES, HIST_NAMES
    use beamid_dynamic_experiments, only: exp_histories_t
    implicit none
    private

    public :: read_history_groups, HISTORY_KEYS

    type :: text_t
        character(len=:), allocatable :: s
    end type text_t
    type :: field_list_t
        type(text_t), allocatable :: f(:)
    end type field_list_t

    character(len=*), parameter :: HISTORY_KEYS = ' experiment target form amplitude start '// &
        'duration f0 f1 w_s t value file column time scale '

contains

    !> The &history groups of deck file f. exp_names: the experiments
    !! (estimation decks; empty for a simulate deck, whose histories are
    !! experiment 1), is_release: which are releases, t_end: each
    !! experiment's last time (its last data row, or the last output time;
    !! negative: unknown, not checked).
    subroutine read_history_groups(f, exp_names, is_release, t_end, hist, errors)
        type(nml_file_t), intent(in) :: f
        character(len=*), intent(in) :: exp_names(:)
        logical, intent(in) :: is_release(:)
        real(dp), intent(in) :: t_end(:)
        type(exp_histories_t), intent(out) :: hist
        character(len=:), allocatable, intent(inout) :: errors
        real(dp), allocatable :: col(:), rows(:, :)
        integer :: k, nh
        logical :: ok
        nh = nml_count(f, 'history')
        allocate (hist%spec(LD_NSPEC + 1, 0), hist%tab(2, 0))
        do k = 1, nh
            associate (g => f%groups(nml_find(f, 'history', k)))
                call read_one(g, col, rows, ok)
                if (.not. ok) cycle
                if (size(rows, 2) > 0) then
                    col(9) = real(size(hist%tab, 2) + 1, dp)
                    col(10) = real(size(rows, 2), dp)
                    hist%tab = reshape([hist%tab, rows], [2, size(hist%tab, 2) + size(rows, 2)])
                end if
                hist%spec = reshape([hist%spec, col], [LD_NSPEC + 1, size(hist%spec, 2) + 1])
            end associate
        end do
    contains
        !> One group: its column and table rows (ok false after an error).
        subroutine read_one(g, col, rows, ok)
            type(nml_group_t), intent(in) :: g
            real(dp), allocatable, intent(out) :: col(:), rows(:, :)
            logical, intent(out) :: ok
            character(len=:), allocatable :: where, exp, target, form, file, column, time
            real(dp) :: amp, t0, dur, f0, f1, ws, period, scale
            real(dp), allocatable :: tt(:), vv(:)
            integer :: e, tg, kind, nerr, i, nt, nv
            logical :: given, sim
            nerr = count_lines(errors)
            where = f%path//', line '//fmt_int(g%line)//': &history '
            sim = size(exp_names) == 0
            allocate (col(LD_NSPEC + 1), source=0.0_dp)
            allocate (rows(2, 0))
            ok = .false.
            call nml_check_keys(f, g, HISTORY_KEYS, errors)
            exp = ''
            target = ''
            form = ''
            call nml_str(f, g, 'experiment', exp, given, errors)
            call nml_str(f, g, 'target', target, given, errors)
            call nml_str(f, g, 'form', form, given, errors)
            target = lower(trim(adjustl(target)))
            form = lower(trim(adjustl(form)))
            e = 1
            if (sim) then
                if (given .and. nml_given(g, 'experiment')) call add_error(errors, where// &
                    "experiment = '"//exp//"': a simulate deck's histories act on its one run "// &
                    '(leave experiment out)')
            else
                e = 0
                do i = 1, size(exp_names)
                    if (trim(exp_names(i)) == trim(adjustl(exp))) e = i
                end do
                if (e == 0) then
                    call add_error(errors, where//"experiment = '"//exp//"', expected the "// &
                                   'name of a release &experiment')
                else if (.not. is_release(e)) then
                    call add_error(errors, where//"experiment = '"//exp//"' is a static "// &
                                   "experiment: histories act on kind = 'release' only")
                end if
            end if
            ! the targets and forms by their codes in beamid_loads (TARGET_*, HIST_*)
            tg = name_index(TARGET_NAMES, target)
            if (tg == 0) call add_error(errors, where//"target = '"//target//"', expected "// &
                                        'one of:'//spaced(TARGET_NAMES))
            kind = name_index(HIST_NAMES, form)
            if (kind == 0) call add_error(errors, where//"form = '"//form//"', expected "// &
                                          'one of:'//spaced(HIST_NAMES))
            if (tg == 0 .or. kind == 0) return
            if (tg == TARGET_HUB .neqv. (kind == HIST_SPIN_UP .or. &
                                         (tg == TARGET_HUB .and. kind == HIST_TABLE))) then
                call add_error(errors, where//"target = '"//target//"' with form = '"//form// &
                               "': the hub takes form 'spin_up' or 'table' (its angle), the "// &
                               "tip loads 'half_sine', 'step', 'chirp' or 'table'")
                return
            end if
            amp = 0.0_dp
            t0 = 0.0_dp
            dur = 0.0_dp
            f0 = 0.0_dp
            f1 = 0.0_dp
            ws = 0.0_dp
            period = 0.0_dp
            scale = 1.0_dp
            call nml_real(f, g, 'amplitude', amp, given, errors)
            call nml_real(f, g, 'start', t0, given, errors)
            call nml_real(f, g, 'duration', dur, given, errors)
            call nml_real(f, g, 'f0', f0, given, errors)
            call nml_real(f, g, 'f1', f1, given, errors)
            call nml_real(f, g, 'w_s', ws, given, errors)
            call nml_real(f, g, 'scale', scale, given, errors)
            call only(' amplitude start duration f0 f1 w_s t value file column time scale ', &
                      allowed(kind))
            if (count_lines(errors) > nerr) return
            select case (kind)
            case (HIST_HALF_SINE, HIST_CHIRP)
                call need('amplitude')
                call need('duration')
                if (nml_given(g, 'duration') .and. .not. dur > 0.0_dp) call add_error(errors, &
                    where//'duration = '//fmt_real(dur)//', expected > 0 (s)')
                if (kind == HIST_CHIRP) then
                    call need('f0')
                    call need('f1')
                    if (f0 < 0.0_dp .or. f1 < 0.0_dp) call add_error(errors, where//'f0 = '// &
                        fmt_real(f0)//', f1 = '//fmt_real(f1)//', expected >= 0 (Hz)')
                end if
            case (HIST_STEP)
                call need('amplitude')
            case (HIST_SPIN_UP)
                call need('w_s')
                call need('t')
                call nml_real(f, g, 't', period, given, errors)
                if (nml_given(g, 't') .and. .not. period > 0.0_dp) call add_error(errors, &
                    where//'T = '//fmt_real(period)//', expected > 0 (the spin-up time, s)')
                amp = ws
                dur = period
            case (HIST_TABLE)
                amp = scale
                if (nml_given(g, 'file')) then
                    if (nml_given(g, 't') .or. nml_given(g, 'value')) call add_error(errors, &
                        where//'give the rows inline (t, value) or in a file (file, column), '// &
                        'not both')
                    file = ''
                    column = ''
                    time = 't'
                    call nml_str(f, g, 'file', file, given, errors)
                    call nml_str(f, g, 'column', column, given, errors)
                    if (.not. given) call add_error(errors, where//'column is missing: the '// &
                                                    "file's column of the values")
                    call nml_str(f, g, 'time', time, given, errors)
                    if (count_lines(errors) > nerr) return
                    call read_csv_rows(relative_to(f%path, trim(file)), trim(column), &
                                       trim(time), tt, vv, errors)
                else
                    nt = count_values(g, 't')
                    nv = count_values(g, 'value')
                    allocate (tt(nt), vv(nv))
                    call nml_reals(f, g, 't', tt, nt, errors)
                    call nml_reals(f, g, 'value', vv, nv, errors)
                    if (count_lines(errors) > nerr) return
                    if (nt == 0 .or. nt /= nv) call add_error(errors, where//'t has '// &
                        fmt_int(nt)//' values and value '//fmt_int(nv)// &
                        ', expected the same number (at least one row)')
                    do i = 2, nt
                        if (.not. tt(i) > tt(i - 1)) then
                            call add_error(errors, where//'t('//fmt_int(i)//') = '// &
                                           fmt_real(tt(i))//' is not after t('//fmt_int(i - 1)// &
                                           ') = '//fmt_real(tt(i - 1))//' (times must increase)')
                            exit
                        end if
                    end do
                end if
                if (count_lines(errors) > nerr) return
                if (tg == TARGET_HUB .and. size(tt) < 2) then
                    call add_error(errors, where//'the hub angle table needs at least 2 rows')
                    return
                end if
                deallocate (rows)
                allocate (rows(2, size(tt)))
                rows(1, :) = tt
                rows(2, :) = vv
                t0 = tt(1)
            end select
            if (count_lines(errors) > nerr) return
            if (e > 0 .and. e <= size(t_end) .and. kind /= HIST_TABLE .and. &
                kind /= HIST_SPIN_UP) then
                if (t_end(e) >= 0.0_dp .and. t0 > t_end(e)) then
                    call add_error(errors, where//'start = '//fmt_real(t0)//' s is after the '// &
                                   "experiment's last time "//fmt_real(t_end(e))//' s')
                    return
                end if
            end if
            if (kind == HIST_TABLE .and. e > 0 .and. e <= size(t_end)) then
                if (t_end(e) >= 0.0_dp .and. t0 > t_end(e)) then
                    call add_error(errors, where//'the table starts at t = '//fmt_real(t0)// &
                                   " s, after the experiment's last time "// &
                                   fmt_real(t_end(e))//' s')
                    return
                end if
            end if
            col(1:LD_NSPEC - 1) = [real(e, dp), real(tg, dp), real(kind, dp), amp, &
                                   merge(0.0_dp, t0, kind == HIST_TABLE), dur, f0, f1]
            ok = .true.
        end subroutine read_one

        !> The fields a form takes (' key ' words).
        pure function allowed(kind) result(keys)
            integer, intent(in) :: kind
            character(len=:), allocatable :: keys
            select case (kind)
            case (HIST_HALF_SINE)
                keys = ' amplitude duration start '
            case (HIST_STEP)
                keys = ' amplitude start '
            case (HIST_CHIRP)
                keys = ' amplitude duration start f0 f1 '
            case (HIST_SPIN_UP)
                keys = ' w_s t '
            case default
                keys = ' t value file column time scale '
            end select
        end function allowed

        !> An error for each key of `keys` given in the group but not in `ok_keys`.
        subroutine only(keys, ok_keys)
            character(len=*), intent(in) :: keys, ok_keys
            integer :: i, j
            associate (g => f%groups(nml_find(f, 'history', k)))
                do i = 1, size(g%items)
                    j = index(keys, ' '//g%items(i)%key//' ')
                    if (j > 0 .and. index(ok_keys, ' '//g%items(i)%key//' ') == 0) &
                        call add_error(errors, nml_where(f, g, g%items(i))//' is not a field '// &
                                       'of this form (it takes:'//ok_keys(:len(ok_keys) - 1)//')')
                end do
            end associate
        end subroutine only

        subroutine need(key)
            character(len=*), intent(in) :: key
            associate (g => f%groups(nml_find(f, 'history', k)))
                if (nml_given(g, key)) return
                if (key == 't') then
                    call add_error(errors, f%path//', line '//fmt_int(g%line)// &
                                   ': &history T is missing (the spin-up time, s)')
                else
                    call add_error(errors, f%path//', line '//fmt_int(g%line)//': &history '// &
                                   key//' is missing')
                end if
            end associate
        end subroutine need
    end subroutine read_history_groups

    !> Position of `word` among the ' '-separated words of `list` (0: none).
    !> Position of `word` in `names` (0: not there).
    pure integer function name_index(names, word)
        character(len=*), intent(in) :: names(:), word
        integer :: i
        name_index = 0
        do i = 1, size(names)
            if (len_trim(word) > 0 .and. trim(names(i)) == trim(word)) name_index = i
        end do
    end function name_index

    !> The names, each after a space (for messages).
    pure function spaced(names) result(text)
        character(len=*), intent(in) :: names(:)
        character(len=:), allocatable :: text
        integer :: i
        text = ''
        do i = 1, size(names)
            text = text//' '//trim(names(i))
        end do
    end function spaced

    pure integer function count_values(g, key)
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: key
        integer :: i
        count_values = 0
        do i = 1, size(g%items)
            if (g%items(i)%key == key) count_values = g%items(i)%first - 1 + size(g%items(i)%values)
        end do
    end function count_values

    pure integer function count_lines(text)
        character(len=:), allocatable, intent(in) :: text
        integer :: k
        count_lines = 0
        if (.not. allocated(text)) return
        do k = 1, len(text)
            if (text(k:k) == new_line('a')) count_lines = count_lines + 1
        end do
        if (len(text) > 0) then
            if (text(len(text):len(text)) /= new_line('a')) count_lines = count_lines + 1
        end if
    end function count_lines

    !> `file` relative to the directory of `deck` (absolute paths as given).
    pure function relative_to(deck, file) result(path)
        character(len=*), intent(in) :: deck, file
        character(len=:), allocatable :: path
        integer :: slash
        if (len(file) > 0) then
            if (file(1:1) == '/') then
                path = file
                return
            end if
        end if
        slash = index(deck, '/', back=.true.)
        path = deck(:slash)//file
    end function relative_to

    !> The rows (time, column) of a CSV file with a header; every bad entry
    !! an error naming the file, line and field.
    subroutine read_csv_rows(path, column, time, tt, vv, errors)
        character(len=*), intent(in) :: path, column, time
        real(dp), allocatable, intent(out) :: tt(:), vv(:)
        character(len=:), allocatable, intent(inout) :: errors
        character(len=:), allocatable :: line
        type(field_list_t) :: head, row
        integer :: u, ios, ln, it, iv
        real(dp) :: x(2)
        logical :: eof
        allocate (tt(0), vv(0))
        open (newunit=u, file=path, status='old', action='read', iostat=ios)
        if (ios /= 0) then
            call add_error(errors, path//': cannot be read (the &history file)')
            return
        end if
        call get_line(u, line, eof)
        ln = 1
        if (eof) then
            call add_error(errors, path//": empty, expected a header with '"//time// &
                           "' and '"//column//"'")
            close (u)
            return
        end if
        head = split(line)
        it = find(head, time)
        iv = find(head, column)
        if (it == 0 .or. iv == 0) then
            if (it == 0) then
                call add_error(errors, path//", line 1: no column '"//time//"' (header: "// &
                               line//')')
            else
                call add_error(errors, path//", line 1: no column '"//column//"' (header: "// &
                               line//')')
            end if
            close (u)
            return
        end if
        do
            call get_line(u, line, eof)
            if (eof) exit
            ln = ln + 1
            if (len_trim(line) == 0) cycle
            row = split(line)
            if (.not. number(row, it, time, x(1)) .or. .not. number(row, iv, column, x(2))) exit
            if (size(tt) > 0) then
                if (.not. x(1) > tt(size(tt))) then
                    call add_error(errors, path//', line '//fmt_int(ln)//": field '"//time// &
                                   "' = "//fmt_real(x(1))//" is not after the previous row's "// &
                                   fmt_real(tt(size(tt)))//' (times must increase)')
                    exit
                end if
            end if
            tt = [tt, x(1)]
            vv = [vv, x(2)]
        end do
        close (u)
        if (size(tt) == 0) call add_error(errors, path//': no rows')
    contains
        logical function number(r, i, name, v)
            type(field_list_t), intent(in) :: r
            integer, intent(in) :: i
            character(len=*), intent(in) :: name
            real(dp), intent(out) :: v
            integer :: ios2
            v = 0.0_dp
            number = .false.
            ios2 = 1
            if (i <= size(r%f)) read (r%f(i)%s, *, iostat=ios2) v
            if (ios2 /= 0 .or. .not. ieee_is_finite(v)) then
                if (i <= size(r%f)) then
                    call add_error(errors, path//', line '//fmt_int(ln)//": field '"//name// &
                                   "' = '"//r%f(i)%s//"', expected a number")
                else
                    call add_error(errors, path//', line '//fmt_int(ln)//": field '"//name// &
                                   "' is missing")
                end if
                return
            end if
            number = .true.
        end function number
    end subroutine read_csv_rows

    !> One line of unit u, any length (eof at the end of the file).
    subroutine get_line(u, line, eof)
        integer, intent(in) :: u
        character(len=:), allocatable, intent(out) :: line
        logical, intent(out) :: eof
        character(len=256) :: buf
        integer :: ios, sz
        line = ''
        eof = .false.
        do
            read (u, '(a)', advance='no', iostat=ios, size=sz) buf
            line = line//buf(:sz)
            if (is_iostat_end(ios)) then
                eof = len(line) == 0
                return
            end if
            if (ios /= 0) return     ! end of record
        end do
    end subroutine get_line


    !> The comma-separated fields of a line (blanks around them dropped).
    pure function split(line) result(r)
        character(len=*), intent(in) :: line
        type(field_list_t) :: r
        integer :: a, b
        allocate (r%f(0))
        a = 1
        do
            b = index(line(a:), ',')
            if (b == 0) then
                r%f = [r%f, text_t(trim(adjustl(line(a:))))]
                exit
            end if
            r%f = [r%f, text_t(trim(adjustl(line(a:a + b - 2))))]
            a = a + b
        end do
    end function split

    pure integer function find(r, name)
        type(field_list_t), intent(in) :: r
        character(len=*), intent(in) :: name
        integer :: i
        find = 0
        do i = 1, size(r%f)
            if (r%f(i)%s == name) then
                find = i
                return
            end if
        end do
    end function find

end module beamid_deck_history
