!> A namelist file split into its groups and items, with typed access and
!! error collection (the reader of the decks, docs/decks.md).
!!
!! The whole file is read into memory and scanned once: each `&group ... /`
!! is located (quotes and `!` comments respected), so a group that is absent
!! is told apart from one that is cut short (no closing `/`) or one whose
!! values do not parse. Each item `key = v1, v2, ...` (or `key(i) = ...`,
!! `r*value` repeats) keeps its raw tokens and line; the typed getters check
!! the tokens against the field's type (a number, an integer, a quoted
!! string, a logical; never NaN or Infinity) and append one message per
!! problem to `errors` (newline separated) naming the file, the group, the
!! key, the value and what was expected. Nothing is defaulted silently.
!! Library code: no printing, no STOP.
module beamid_namelist
    use, intrinsic :: iso_fortran_env, only: int64
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_IO, fmt_int, lower
    implicit none
    private

    public :: nml_file_t, nml_group_t, nml_item_t, nml_text_t, nml_read_file, nml_count, &
              nml_find, nml_check_keys, nml_real, nml_reals, nml_int, nml_str, nml_strs, &
              nml_logical, nml_given, add_error, nml_where, nml_ints, nml_merge_items

    type :: nml_text_t
        character(len=:), allocatable :: s
    end type nml_text_t

    !> One `key = values` item of a group.
    type :: nml_item_t
        character(len=:), allocatable :: key        !< lower case, without subscript
        character(len=:), allocatable :: name       !< as written (for messages)
        integer :: first = 1                        !< first index (`key(i) = ...`)
        integer :: line = 0
        type(nml_text_t), allocatable :: values(:)  !< raw tokens (strings unquoted)
        logical, allocatable :: quoted(:)
    end type nml_item_t

    !> One `&name ... /` group.
    type :: nml_group_t
        character(len=:), allocatable :: name       !< lower case
        !> How messages name the group when not '&name' (e.g. an experiment
        !! by its name: "&experiment 'F2'").
        character(len=:), allocatable :: label
        integer :: line = 0
        type(nml_item_t), allocatable :: items(:)
    end type nml_group_t

    type :: nml_file_t
        character(len=:), allocatable :: path
        type(nml_group_t), allocatable :: groups(:)
    end type nml_file_t

contains

    !> Read and split a namelist file. A file that cannot be read sets `stat`
    !! (ERR_IO); syntax problems (a group not closed by '/', text outside the
    !! groups, an item without '=') go to `errors`.
    subroutine nml_read_file(path, file, errors, stat)
        character(len=*), intent(in) :: path
        type(nml_file_t), intent(out) :: file
        character(len=:), allocatable, intent(inout) :: errors
        type(status_t), intent(inout) :: stat
        character(len=:), allocatable :: text
        character(len=512) :: msg
        integer :: unit, ios
        integer(int64) :: fsize
        logical :: exists, isdir

        file%path = path
        allocate (file%groups(0))
        inquire (file=path, exist=exists)
        inquire (file=path//'/.', exist=isdir)
        if (isdir) then
            call set_status(stat, ERR_IO, 'cannot read '//path, 'it is a directory, not a deck')
            return
        end if
        if (.not. exists) then
            call set_status(stat, ERR_IO, 'cannot open '//path, 'no such file')
            return
        end if
        open (newunit=unit, file=path, status='old', action='read', access='stream', &
              form='unformatted', iostat=ios, iomsg=msg)
        if (ios /= 0) then
            call set_status(stat, ERR_IO, 'cannot open '//path, trim(msg))
            return
        end if
        inquire (unit=unit, size=fsize)
        if (fsize < 0 .or. fsize > 100000000_int64) then
            close (unit)
            call set_status(stat, ERR_IO, 'cannot read '//path, 'not a deck (size '// &
                            fmt_int(int(min(fsize, 2000000000_int64)))//' bytes)')
            return
        end if
        allocate (character(len=fsize) :: text)
        if (fsize > 0) read (unit, iostat=ios, iomsg=msg) text
        close (unit)
        if (ios /= 0) then
            call set_status(stat, ERR_IO, 'cannot read '//path, trim(msg))
            return
        end if
        call scan_text(text, file, errors)
    end subroutine nml_read_file

    !> Items given apart from the file (`text`: `key = values` items, as in a
    !! group, e.g. a command line's options) merged into the first group
    !! `name` of `file`: an item replaces the group's item of its key, or is
    !! added. Syntax problems go to `errors`, named `where`.
    subroutine nml_merge_items(file, name, text, where, errors)
        type(nml_file_t), intent(inout) :: file
        character(len=*), intent(in) :: name, text, where
        character(len=:), allocatable, intent(inout) :: errors
        type(nml_file_t) :: extra
        character(len=:), allocatable :: found
        integer :: g, i, k
        if (len_trim(text) == 0) return
        extra%path = where
        allocate (extra%groups(0))
        found = ''
        call scan_text('&'//name//new_line('a')//text//new_line('a')//'/'//new_line('a'), &
                       extra, found)
        if (len(found) > 0) then
            errors = errors//found
            return
        end if
        g = nml_find(file, name, 1)
        if (g == 0 .or. size(extra%groups) /= 1) return
        associate (grp => file%groups(g))
            do i = 1, size(extra%groups(1)%items)
                k = item_index(grp, extra%groups(1)%items(i)%key)
                if (k > 0) then
                    grp%items(k) = extra%groups(1)%items(i)
                else
                    grp%items = [grp%items, extra%groups(1)%items(i)]
                end if
            end do
        end associate
    end subroutine nml_merge_items

    !> Split the text into groups and items.
    subroutine scan_text(text, file, errors)
        character(len=*), intent(in) :: text
        type(nml_file_t), intent(inout) :: file
        character(len=:), allocatable, intent(inout) :: errors
        integer :: i, n, line, j
        character(len=:), allocatable :: name
        type(nml_group_t) :: g
        logical :: skipped
        n = len(text)
        i = 1
        line = 1
        ! a measurement CSV (no group, its header): said in one line, not one error per line
        if (scan(text, '&$') == 0 .and. index(text, 'experiment,t,quantity') > 0) then
            call add_error(errors, file%path//': a measurement CSV file (experiment,t,'// &
                           'quantity,value,sigma), not a deck: name it in a deck''s &fit '// &
                           "group, data = '"//file%path//"' (docs/decks.md)")
            return
        end if
        do while (i <= n)
            call skip_blank(text, i, line, skipped)
            if (skipped) cycle
            select case (text(i:i))
            case ('&', '$')
                j = i + 1
                do while (j <= n)
                    if (.not. is_name_char(text(j:j))) exit
                    j = j + 1
                end do
                name = lower(text(i + 1:j - 1))
                if (len(name) == 0) then
                    call add_error(errors, file%path//', line '//fmt_int(line)// &
                                   ": '&' without a group name")
                    i = j
                    cycle
                end if
                g = nml_group_t()
                g%name = name
                g%line = line
                allocate (g%items(0))
                i = j
                call scan_group(text, i, line, file%path, g, errors)
                file%groups = [file%groups, g]
            case default
                j = i
                do while (j <= n)
                    if (text(j:j) == new_line('a')) exit
                    j = j + 1
                end do
                call add_error(errors, file%path//', line '//fmt_int(line)// &
                               ': text outside a group: '//printable(text(i:min(j - 1, i + 40))))
                i = j
            end select
        end do
    end subroutine scan_text

    !> The items of one group, from after its name to its closing '/' (or an
    !! old-style '&end'): a name followed by '=' starts an item, the values up
    !! to the next one are its values (quoted strings, r*value repeats).
    subroutine scan_group(text, i, line, path, g, errors)
        character(len=*), intent(in) :: text, path
        integer, intent(inout) :: i, line
        type(nml_group_t), intent(inout) :: g
        character(len=:), allocatable, intent(inout) :: errors
        integer :: n, j, nval
        type(nml_item_t) :: item
        character(len=:), allocatable :: token, at
        logical :: have_item, closed, orphan, skipped
        n = len(text)
        have_item = .false.
        closed = .false.
        orphan = .false.
        nval = 0
        do while (i <= n)
            call skip_blank(text, i, line, skipped)
            if (skipped) cycle
            select case (text(i:i))
            case ('/')
                i = i + 1
                closed = .true.
                exit
            case ('&', '$')
                ! '&end' closes a group in the old style
                if (lower(text(i + 1:min(n, i + 3))) == 'end') then
                    i = i + 4
                    closed = .true.
                end if
                exit
            case ("'", '"')
                call read_quoted(text, i, line, token)
                call add_value(token, .true.)
            case default
                j = bare_token_end(text, i)
                token = text(i:j - 1)
                at = path//', line '//fmt_int(line)//': &'//g%name
                if (len(token) == 0) then
                    ! '=' right where a name should be: its values are not
                    ! reported again
                    call add_error(errors, at//": '=' without a variable name")
                    if (have_item) call push_item()
                    orphan = .true.
                    i = j + 1
                else if (next_is_equals(text, j)) then
                    if (have_item) call push_item()
                    item = new_item(token, line, at, errors)
                    have_item = .true.
                    orphan = .false.
                    i = j + index(text(j:), '=')
                else
                    i = j
                    call add_values(token, j)
                end if
            end select
        end do
        if (have_item) call push_item()
        if (.not. closed) call add_error(errors, path//', line '//fmt_int(g%line)//': group &'// &
            g%name//" is not closed by '/' (the deck is cut short, or a '/' is missing "// &
            'before the next group)')

    contains

        !> The values of a bare token ending before text(j:j): the token
        !! itself, or r copies of the value of an r*value token (r*'text'
        !! reads the quoted text that starts after the '*').
        subroutine add_values(token, j)
            character(len=:), allocatable, intent(inout) :: token
            integer, intent(in) :: j
            integer :: rep, k
            logical :: quoted
            rep = repeat_count(token)
            if (rep == 0) then
                call add_value(token, .false.)
                return
            end if
            token = token(index(token, '*') + 1:)
            quoted = .false.
            if (len(token) > 0) quoted = token(1:1) == "'" .or. token(1:1) == '"'
            if (quoted) then
                i = j - len(token)
                call read_quoted(text, i, line, token)
            end if
            do k = 1, rep
                call add_value(token, quoted)
            end do
        end subroutine add_values

        !> Append a value (capacity doubled when full: long lists stay O(n)).
        subroutine add_value(value, is_quoted)
            character(len=*), intent(in) :: value
            logical, intent(in) :: is_quoted
            type(nml_text_t), allocatable :: grown(:)
            logical, allocatable :: grown_q(:)
            if (.not. have_item) then
                if (orphan) return
                orphan = .true.
                call add_error(errors, path//', line '//fmt_int(line)//': &'//g%name// &
                               ' value '//value//' without a variable name (expected key = value)')
                return
            end if
            if (nval == size(item%values)) then
                allocate (grown(max(8, 2*nval)), grown_q(max(8, 2*nval)))
                grown(:nval) = item%values(:nval)
                grown_q(:nval) = item%quoted(:nval)
                call move_alloc(grown, item%values)
                call move_alloc(grown_q, item%quoted)
            end if
            nval = nval + 1
            item%values(nval)%s = value
            item%quoted(nval) = is_quoted
        end subroutine add_value

        subroutine push_item()
            item%values = item%values(:nval)
            item%quoted = item%quoted(:nval)
            g%items = [g%items, item]
            have_item = .false.
            nval = 0
        end subroutine push_item
    end subroutine scan_group

    !> A new item from its name token, key or key(index), on line `line`;
    !! `at` starts the message of a bad index.
    function new_item(token, line, at, errors) result(item)
        character(len=*), intent(in) :: token, at
        integer, intent(in) :: line
        character(len=:), allocatable, intent(inout) :: errors
        type(nml_item_t) :: item
        integer :: k, ios
        item%line = line
        allocate (item%values(0), item%quoted(0))
        k = index(token, '(')
        if (k == 0) k = len(token) + 1
        item%key = lower(token(:k - 1))
        item%name = token(:k - 1)
        if (k > len(token)) return
        read (token(k + 1:max(k, len(token) - 1)), *, iostat=ios) item%first
        if (ios /= 0 .or. token(len(token):) /= ')' .or. item%first < 1) then
            call add_error(errors, at//' '//token//': expected key(index) with an index >= 1')
            item%first = 1
        end if
    end function new_item

    !> The r of an r*value token; 0 when it is not one (no '*' after a count
    !! of digits, or a count outside 1..1000000: the token is a plain value).
    pure integer function repeat_count(token) result(rep)
        character(len=*), intent(in) :: token
        integer :: k, ios
        rep = 0
        k = index(token, '*')
        if (k <= 1) return
        if (verify(token(:k - 1), '0123456789') /= 0) return
        read (token(:k - 1), *, iostat=ios) rep
        if (ios /= 0 .or. rep < 1 .or. rep > 1000000) rep = 0
    end function repeat_count

    !> End (exclusive) of the bare token starting at text(i:i): the first
    !! blank, comma, '/', '!', '&', '$', newline or '='.
    pure integer function bare_token_end(text, i) result(j)
        character(len=*), intent(in) :: text
        integer, intent(in) :: i
        j = i
        do while (j <= len(text))
            if (index(' ,/!&$='//char(9)//char(13)//new_line('a'), text(j:j)) > 0) exit
            j = j + 1
        end do
    end function bare_token_end

    !> Step over a blank, comma, newline (counted in `line`) or comment at
    !! text(i:i); skipped is false, and nothing done, at anything else.
    pure subroutine skip_blank(text, i, line, skipped)
        character(len=*), intent(in) :: text
        integer, intent(inout) :: i, line
        logical, intent(out) :: skipped
        skipped = .true.
        select case (text(i:i))
        case (new_line('a'))
            line = line + 1
            i = i + 1
        case (' ', char(9), char(13), ',')
            i = i + 1
        case ('!')
            call skip_comment(text, i)
        case default
            skipped = .false.
        end select
    end subroutine skip_blank

    !> A quoted string starting at text(i:i); doubled quotes stand for one.
    subroutine read_quoted(text, i, line, token)
        character(len=*), intent(in) :: text
        integer, intent(inout) :: i, line
        character(len=:), allocatable, intent(out) :: token
        character :: q
        integer :: start
        q = text(i:i)
        token = ''
        i = i + 1
        start = i
        do while (i <= len(text))
            if (text(i:i) == q) then
                token = token//text(start:i - 1)
                if (i < len(text)) then
                    if (text(i + 1:i + 1) == q) then
                        ! a doubled quote stands for one
                        token = token//q
                        i = i + 2
                        start = i
                        cycle
                    end if
                end if
                i = i + 1
                return
            end if
            if (text(i:i) == new_line('a')) line = line + 1
            i = i + 1
        end do
        token = token//text(start:)
    end subroutine read_quoted

    !> Text with control characters shown as '?' (for messages).
    pure function printable(text) result(out)
        character(len=*), intent(in) :: text
        character(len=len(text)) :: out
        integer :: k
        out = text
        do k = 1, len(text)
            if (iachar(text(k:k)) < 32 .or. iachar(text(k:k)) > 126) out(k:k) = '?'
        end do
        out = trim(out)
    end function printable

    pure subroutine skip_comment(text, i)
        character(len=*), intent(in) :: text
        integer, intent(inout) :: i
        do while (i <= len(text))
            if (text(i:i) == new_line('a')) return
            i = i + 1
        end do
    end subroutine skip_comment

    pure logical function next_is_equals(text, j)
        character(len=*), intent(in) :: text
        integer, intent(in) :: j
        integer :: k
        next_is_equals = .false.
        k = j
        do while (k <= len(text))
            if (text(k:k) /= ' ' .and. text(k:k) /= char(9)) exit
            k = k + 1
        end do
        if (k <= len(text)) next_is_equals = text(k:k) == '='
    end function next_is_equals

    pure logical function is_name_char(c)
        character, intent(in) :: c
        is_name_char = (c >= 'a' .and. c <= 'z') .or. (c >= 'A' .and. c <= 'Z') .or. &
                       (c >= '0' .and. c <= '9') .or. c == '_'
    end function is_name_char

    !> Append one line to the error list.
    pure subroutine add_error(errors, text)
        character(len=:), allocatable, intent(inout) :: errors
        character(len=*), intent(in) :: text
        character(len=len(text)) :: line
        integer :: k
        ! one problem, one line: control characters of a value (a newline in
        ! a string cut short) become spaces
        line = text
        do k = 1, len(line)
            if (iachar(line(k:k)) < 32) line(k:k) = ' '
        end do
        if (.not. allocated(errors)) errors = ''
        errors = errors//line//new_line('a')
    end subroutine add_error

    !> Number of groups of that name.
    pure integer function nml_count(file, name)
        type(nml_file_t), intent(in) :: file
        character(len=*), intent(in) :: name
        integer :: k
        nml_count = 0
        do k = 1, size(file%groups)
            if (file%groups(k)%name == name) nml_count = nml_count + 1
        end do
    end function nml_count

    !> Index of the n-th group of that name (0: none).
    pure integer function nml_find(file, name, nth)
        type(nml_file_t), intent(in) :: file
        character(len=*), intent(in) :: name
        integer, intent(in), optional :: nth
        integer :: k, seen, want
        want = 1
        if (present(nth)) want = nth
        seen = 0
        nml_find = 0
        do k = 1, size(file%groups)
            if (file%groups(k)%name == name) then
                seen = seen + 1
                if (seen == want) then
                    nml_find = k
                    return
                end if
            end if
        end do
    end function nml_find

    !> '<path>, line N: &group key' for messages.
    pure function nml_where(file, g, it) result(text)
        type(nml_file_t), intent(in) :: file
        type(nml_group_t), intent(in) :: g
        type(nml_item_t), intent(in) :: it
        character(len=:), allocatable :: text
        if (allocated(g%label)) then
            text = file%path//', line '//fmt_int(it%line)//': '//g%label//' '//it%name
        else
            text = file%path//', line '//fmt_int(it%line)//': &'//g%name//' '//it%name
        end if
    end function nml_where

    !> Unknown and repeated keys of a group; `known` is ' key1 key2 ... '.
    subroutine nml_check_keys(file, g, known, errors)
        type(nml_file_t), intent(in) :: file
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: known
        character(len=:), allocatable, intent(inout) :: errors
        integer :: k, j
        do k = 1, size(g%items)
            associate (it => g%items(k))
                if (index(known, ' '//it%key//' ') == 0) then
                    call add_error(errors, file%path//', line '//fmt_int(it%line)//': &'// &
                                   g%name//" has no variable '"//it%name//"'; valid: "// &
                                   trim(adjustl(known)))
                    cycle
                end if
                do j = 1, k - 1
                    if (g%items(j)%key == it%key) then
                        call add_error(errors, nml_where(file, g, it)//' is given twice '// &
                                       '(also on line '//fmt_int(g%items(j)%line)//')')
                        exit
                    end if
                end do
            end associate
        end do
    end subroutine nml_check_keys

    !> Index of the item of that key in the group (0: not given).
    pure integer function item_index(g, key)
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: key
        integer :: k
        item_index = 0
        do k = 1, size(g%items)
            if (g%items(k)%key == key) then
                item_index = k
                return
            end if
        end do
    end function item_index

    !> True when the group gives that key.
    pure logical function nml_given(g, key)
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: key
        nml_given = item_index(g, key) > 0
    end function nml_given

    !> The value text of an item for messages.
    pure function shown(it) result(text)
        type(nml_item_t), intent(in) :: it
        character(len=:), allocatable :: text
        integer :: k
        text = ''
        do k = 1, size(it%values)
            if (k > 1) text = text//', '
            if (it%quoted(k)) then
                text = text//"'"//it%values(k)%s//"'"
            else
                text = text//it%values(k)%s
            end if
            if (len(text) > 60) then
                text = text//', ...'
                return
            end if
        end do
        if (size(it%values) == 0) text = '(nothing)'
    end function shown

    !> A finite real from a token (NaN, Infinity and non-numbers refused).
    subroutine parse_real(token, quoted, x, ok)
        character(len=*), intent(in) :: token
        logical, intent(in) :: quoted
        real(dp), intent(out) :: x
        logical, intent(out) :: ok
        integer :: ios
        x = 0.0_dp
        ok = .false.
        if (quoted .or. len_trim(token) == 0) return
        if (verify(token, '0123456789+-.eEdD') /= 0) return
        if (scan(token, '0123456789') == 0) return
        read (token, *, iostat=ios) x
        ok = ios == 0 .and. ieee_is_finite(x)
    end subroutine parse_real

    !> An integer from a token: optional sign and digits only.
    subroutine parse_int(token, quoted, i, ok, too_big)
        character(len=*), intent(in) :: token
        logical, intent(in) :: quoted
        integer, intent(out) :: i
        logical, intent(out) :: ok, too_big
        integer(int64) :: big
        integer :: ios, start
        i = 0
        ok = .false.
        too_big = .false.
        if (quoted .or. len_trim(token) == 0) return
        start = 1
        if (token(1:1) == '+' .or. token(1:1) == '-') start = 2
        if (start > len(token)) return
        if (verify(token(start:), '0123456789') /= 0) return
        if (len(token) - start + 1 > 18) then
            too_big = .true.
            return
        end if
        read (token, *, iostat=ios) big
        if (ios /= 0) return
        if (abs(big) > int(huge(i), int64)) then
            too_big = .true.
            return
        end if
        i = int(big)
        ok = .true.
    end subroutine parse_int

    !> One real: `given` tells whether the group sets it (else x is unchanged).
    subroutine nml_real(file, g, key, x, given, errors)
        type(nml_file_t), intent(in) :: file
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: key
        real(dp), intent(inout) :: x
        logical, intent(out) :: given
        character(len=:), allocatable, intent(inout) :: errors
        integer :: k
        logical :: ok
        real(dp) :: v
        k = item_index(g, key)
        given = k > 0
        if (.not. given) return
        associate (it => g%items(k))
            ok = size(it%values) == 1 .and. it%first == 1
            if (ok) call parse_real(it%values(1)%s, it%quoted(1), v, ok)
            if (.not. ok) then
                call add_error(errors, nml_where(file, g, it)//' = '//shown(it)// &
                               ': expected one finite number')
                given = .false.
                return
            end if
            x = v
        end associate
    end subroutine nml_real

    !> A list of reals into x(first:...); n is the last index set (0: not
    !! given). More than size(x) values is an error naming the expected size.
    subroutine nml_reals(file, g, key, x, n, errors, what)
        type(nml_file_t), intent(in) :: file
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: key
        real(dp), intent(inout) :: x(:)
        integer, intent(out) :: n
        character(len=:), allocatable, intent(inout) :: errors
        character(len=*), intent(in), optional :: what
        integer :: k, j
        logical :: ok, bad
        real(dp) :: v
        character(len=:), allocatable :: why
        n = 0
        k = item_index(g, key)
        if (k == 0) return
        associate (it => g%items(k))
            if (size(it%values) == 0) then
                call add_error(errors, nml_where(file, g, it)//' has no value: expected '// &
                               'a list of numbers')
                return
            end if
            if (it%first - 1 + size(it%values) > size(x)) then
                why = ''
                if (present(what)) why = ' ('//what//')'
                call add_error(errors, nml_where(file, g, it)//' = '//shown(it)//': '// &
                               fmt_int(it%first - 1 + size(it%values))// &
                               ' values, expected at most '//fmt_int(size(x))//why)
                return
            end if
            bad = .false.
            do j = 1, size(it%values)
                call parse_real(it%values(j)%s, it%quoted(j), v, ok)
                if (.not. ok) then
                    call add_error(errors, nml_where(file, g, it)//'('// &
                                   fmt_int(it%first + j - 1)//') = '// &
                                   quoted_text(it%values(j)%s, it%quoted(j))// &
                                   ': expected a finite number')
                    bad = .true.
                    cycle
                end if
                x(it%first + j - 1) = v
            end do
            if (.not. bad) n = it%first + size(it%values) - 1
        end associate
    end subroutine nml_reals

    !> One integer (a value like 2.5 or 'four' is an error, never rounded).
    subroutine nml_int(file, g, key, i, given, errors)
        type(nml_file_t), intent(in) :: file
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: key
        integer, intent(inout) :: i
        logical, intent(out) :: given
        character(len=:), allocatable, intent(inout) :: errors
        integer :: k, v
        logical :: ok, too_big
        k = item_index(g, key)
        given = k > 0
        if (.not. given) return
        associate (it => g%items(k))
            ok = size(it%values) == 1 .and. it%first == 1
            too_big = .false.
            if (ok) call parse_int(it%values(1)%s, it%quoted(1), v, ok, too_big)
            if (.not. ok) then
                if (too_big) then
                    call add_error(errors, nml_where(file, g, it)//' = '//shown(it)// &
                                   ': too large (at most '//fmt_int(huge(v))//')')
                else
                    call add_error(errors, nml_where(file, g, it)//' = '//shown(it)// &
                                   ': expected one integer')
                end if
                given = .false.
                return
            end if
            i = v
        end associate
    end subroutine nml_int

    !> A list of integers (all values given, from index 1).
    subroutine nml_ints(file, g, key, list, errors)
        type(nml_file_t), intent(in) :: file
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: key
        integer, allocatable, intent(out) :: list(:)
        character(len=:), allocatable, intent(inout) :: errors
        integer :: k, j, v
        logical :: ok, too_big
        allocate (list(0))
        k = item_index(g, key)
        if (k == 0) return
        associate (it => g%items(k))
            do j = 1, size(it%values)
                call parse_int(it%values(j)%s, it%quoted(j), v, ok, too_big)
                if (.not. ok) then
                    call add_error(errors, nml_where(file, g, it)//'('//fmt_int(j)//') = '// &
                                   quoted_text(it%values(j)%s, it%quoted(j))// &
                                   ': expected an integer')
                    cycle
                end if
                list = [list, v]
            end do
        end associate
    end subroutine nml_ints

    !> One quoted string.
    subroutine nml_str(file, g, key, s, given, errors)
        type(nml_file_t), intent(in) :: file
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: key
        character(len=:), allocatable, intent(inout) :: s
        logical, intent(out) :: given
        character(len=:), allocatable, intent(inout) :: errors
        integer :: k
        k = item_index(g, key)
        given = k > 0
        if (.not. given) return
        associate (it => g%items(k))
            if (size(it%values) /= 1 .or. it%first /= 1) then
                call add_error(errors, nml_where(file, g, it)//' = '//shown(it)// &
                               ': expected one quoted text')
                given = .false.
                return
            end if
            if (.not. it%quoted(1)) then
                call add_error(errors, nml_where(file, g, it)//' = '//shown(it)// &
                               ": expected a quoted text ('...')")
                given = .false.
                return
            end if
            s = it%values(1)%s
        end associate
    end subroutine nml_str

    !> A list of quoted strings (empty entries dropped).
    subroutine nml_strs(file, g, key, list, given, errors)
        type(nml_file_t), intent(in) :: file
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: key
        type(nml_text_t), allocatable, intent(out) :: list(:)
        logical, intent(out) :: given
        character(len=:), allocatable, intent(inout) :: errors
        integer :: k, j
        allocate (list(0))
        k = item_index(g, key)
        given = k > 0
        if (.not. given) return
        associate (it => g%items(k))
            do j = 1, size(it%values)
                if (.not. it%quoted(j)) then
                    call add_error(errors, nml_where(file, g, it)//'('//fmt_int(j)//') = '// &
                                   it%values(j)%s//": expected a quoted name ('...')")
                    cycle
                end if
                if (len_trim(it%values(j)%s) > 0) list = [list, nml_text_t(trim(adjustl( &
                                                          it%values(j)%s)))]
            end do
        end associate
    end subroutine nml_strs

    !> One logical (.true., .false., T, F).
    subroutine nml_logical(file, g, key, b, given, errors)
        type(nml_file_t), intent(in) :: file
        type(nml_group_t), intent(in) :: g
        character(len=*), intent(in) :: key
        logical, intent(inout) :: b
        logical, intent(out) :: given
        character(len=:), allocatable, intent(inout) :: errors
        integer :: k
        character(len=:), allocatable :: v
        k = item_index(g, key)
        given = k > 0
        if (.not. given) return
        associate (it => g%items(k))
            v = ''
            if (size(it%values) == 1 .and. .not. it%quoted(1)) v = lower(it%values(1)%s)
            select case (v)
            case ('.true.', 't', '.t.', 'true')
                b = .true.
            case ('.false.', 'f', '.f.', 'false')
                b = .false.
            case default
                call add_error(errors, nml_where(file, g, it)//' = '//shown(it)// &
                               ': expected .true. or .false.')
                given = .false.
            end select
        end associate
    end subroutine nml_logical

    pure function quoted_text(s, q) result(text)
        character(len=*), intent(in) :: s
        logical, intent(in) :: q
        character(len=:), allocatable :: text
        if (q) then
            text = "'"//s//"'"
        else
            text = s
        end if
    end function quoted_text
end module beamid_namelist
