!> Status returned by every fallible beamid routine.
!!
!! Convention (after LAPACK's INFO and stdlib's state type):
!! code == 0 success; code < 0 bad input (the message names the input, the
!! value and what was expected); code > 0 numerical failure (no convergence,
!! singular matrix) with iteration counts and residuals in the message.
!! Library code never stops and never prints: it fills a status and returns.
module beamid_status
    use, intrinsic :: ieee_arithmetic, only: ieee_is_nan, ieee_is_finite
    use beamid_kinds, only: dp
    implicit none
    private

    public :: status_t, status_out, put_text, set_status, clear_status, fmt_real, fmt_int, lower, &
              exit_code, fmt_bytes, fmt_count, set_alloc_error

    !> Status codes. Negative: input errors. Positive: numerical failures.
    integer, parameter, public :: STATUS_OK = 0
    integer, parameter, public :: ERR_INPUT = -1        !< bad value or name
    integer, parameter, public :: ERR_IO = -2           !< file could not be read or written
    integer, parameter, public :: ERR_DECK = -3         !< malformed namelist deck
    integer, parameter, public :: ERR_NO_CONVERGENCE = 1 !< iteration did not converge
    integer, parameter, public :: ERR_SINGULAR = 2       !< singular or ill-posed linear system
    integer, parameter, public :: ERR_NUMERIC = 3        !< non-finite numbers or lost accuracy
    integer, parameter, public :: ERR_OUTPUT = -4        !< an output file cannot be written
    integer, parameter, public :: ERR_SIZE = -5          !< a size beyond the bound (memory)
    integer, parameter, public :: ERR_INTERNAL = 100     !< a bug: an impossible state

    !> Exit codes of beamid-batch and of the `beamid` command (docs/decks.md):
    !! one per kind of error, the same from both fronts.
    integer, parameter, public :: EXIT_OK = 0            !< success
    integer, parameter, public :: EXIT_NOT_REPRODUCED = 1 !< a published value not reproduced
    integer, parameter, public :: EXIT_BAD_INPUT = 2     !< bad deck, CSV, value or input file
    integer, parameter, public :: EXIT_NUMERIC = 3       !< numerical failure (no convergence)
    integer, parameter, public :: EXIT_OUTPUT = 4        !< an output file cannot be written
    integer, parameter, public :: EXIT_INTERNAL = 5      !< internal error

    !> Memory bound of one computation a user asks for (bytes): sizes are
    !! checked against it before anything is allocated (fmt_bytes for messages).
    real(dp), parameter, public :: MAX_BYTES = 4.0_dp*1024.0_dp**3

    !> Messages have no length limit. The f2py entry points hand them to
    !! Python in a buffer of 256 characters (`character(len=256),
    !! intent(out) :: message`: numpy's f2py needs the literal), filled by
    !! status_out, which says so in the buffer when a message does not fit.
    type :: status_t
        integer :: code = STATUS_OK
        !> What went wrong, any length (unallocated: no message yet).
        character(len=:), allocatable :: message
    contains
        procedure :: ok => status_is_ok
    end type status_t

contains

    !> The (code, message) pair of a status, as the f2py binding returns it:
    !! the message copied into the caller's buffer by put_text.
    pure subroutine status_out(stat, code, message)
        type(status_t), intent(in) :: stat
        integer, intent(out) :: code
        character(len=*), intent(out) :: message
        code = stat%code
        message = ''
        if (allocated(stat%message)) call put_text(stat%message, message)
    end subroutine status_out

    !> Text into a fixed-length buffer (the f2py boundary); text that does
    !! not fit is cut and ends with '... (truncated: N characters)', never
    !! clipped silently.
    pure subroutine put_text(text, buffer)
        character(len=*), intent(in) :: text
        character(len=*), intent(out) :: buffer
        character(len=:), allocatable :: tail
        if (len(text) <= len(buffer)) then
            buffer = text
            return
        end if
        tail = '... (truncated: '//fmt_int(len(text))//' characters)'
        if (len(tail) >= len(buffer)) then
            buffer = tail
        else
            buffer = text(:len(buffer) - len(tail))//tail
        end if
    end subroutine put_text

    !> True when the status holds no error.
    pure logical function status_is_ok(self)
        class(status_t), intent(in) :: self
        status_is_ok = self%code == STATUS_OK
    end function status_is_ok

    !> Record an error: `where` names the routine, `message` says what went wrong.
    pure subroutine set_status(stat, code, where, message)
        type(status_t), intent(inout) :: stat
        integer, intent(in) :: code
        character(len=*), intent(in) :: where
        character(len=*), intent(in) :: message
        stat%code = code
        stat%message = trim(where)//': '//trim(message)
    end subroutine set_status

    !> The exit code of a status code (the one table of exit codes): 0 ok,
    !! 2 bad input (including a missing or unreadable input file and a size
    !! beyond the bound), 3 numerical failure, 4 output not written, 5 internal.
    pure integer function exit_code(code)
        integer, intent(in) :: code
        if (code == STATUS_OK) then
            exit_code = EXIT_OK
        else if (code == ERR_OUTPUT) then
            exit_code = EXIT_OUTPUT
        else if (code < 0) then
            exit_code = EXIT_BAD_INPUT
        else if (code < ERR_INTERNAL) then
            exit_code = EXIT_NUMERIC
        else
            exit_code = EXIT_INTERNAL
        end if
    end function exit_code

    !> Bytes as '1.2 GiB' for messages.
    pure function fmt_bytes(bytes) result(text)
        real(dp), intent(in) :: bytes
        character(len=:), allocatable :: text
        character(len=32) :: buffer
        real(dp) :: x
        character(len=4) :: unit
        x = bytes/1024.0_dp**3
        unit = ' GiB'
        if (bytes < 1024.0_dp**3) then
            x = bytes/1024.0_dp**2
            unit = ' MiB'
        end if
        if (x < 1.0e5_dp) then
            write (buffer, '(f0.1)') x
        else
            write (buffer, '(es10.2)') x
        end if
        buffer = adjustl(buffer)
        if (buffer(1:1) == '.') buffer = '0'//buffer
        text = trim(buffer)//unit
    end function fmt_bytes

    !> A count held in a real (a 64-bit product of sizes) as digits.
    pure function fmt_count(x) result(text)
        real(dp), intent(in) :: x
        character(len=:), allocatable :: text
        character(len=32) :: buffer
        if (abs(x) < 9.0e18_dp) then
            write (buffer, '(i0)') nint(x, kind=selected_int_kind(18))
        else
            write (buffer, '(es10.3)') x
        end if
        text = trim(adjustl(buffer))
    end function fmt_count

    !> An allocation that failed (stat= of allocate): ERR_SIZE naming what
    !! was being allocated and the memory it needed.
    pure subroutine set_alloc_error(stat, where, what, bytes)
        type(status_t), intent(inout) :: stat
        character(len=*), intent(in) :: where, what
        real(dp), intent(in) :: bytes
        call set_status(stat, ERR_SIZE, where, 'cannot allocate '//what//' (about '// &
                        fmt_bytes(bytes)//'): not enough memory')
    end subroutine set_alloc_error

    pure subroutine clear_status(stat)
        type(status_t), intent(inout) :: stat
        stat%code = STATUS_OK
        stat%message = ''
    end subroutine clear_status

    !> Shortest readable form of a real for messages.
    pure function fmt_real(x) result(text)
        real(dp), intent(in) :: x
        character(len=:), allocatable :: text
        character(len=32) :: buffer
        if (ieee_is_nan(x)) then
            text = 'NaN'
        else if (.not. ieee_is_finite(x)) then
            if (x > 0) then
                text = 'Infinity'
            else
                text = '-Infinity'
            end if
        else
            write (buffer, '(g0.8)') x
            text = trim(adjustl(buffer))
        end if
    end function fmt_real

    pure function fmt_int(i) result(text)
        integer, intent(in) :: i
        character(len=:), allocatable :: text
        character(len=16) :: buffer
        write (buffer, '(i0)') i
        text = trim(buffer)
    end function fmt_int

    !> ASCII lower case (namelist group and variable names are case-insensitive).
    pure function lower(text) result(out)
        character(len=*), intent(in) :: text
        character(len=len(text)) :: out
        integer :: i, code
        out = text
        do i = 1, len(text)
            code = iachar(text(i:i))
            if (code >= iachar('A') .and. code <= iachar('Z')) out(i:i) = achar(code + 32)
        end do
    end function lower
end module beamid_status
