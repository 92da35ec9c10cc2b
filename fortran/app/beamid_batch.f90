!> beamid-batch DECK: run a namelist deck without Python (docs/decks.md).
!!
!! Reads and validates the deck once (beamid_deck_run: the deck and its
!! measurement files, held in a local run), runs its task (beamid_tasks:
!! static, fe_static, fe_modes, fit, compare, diagnose, improve, identify,
!! simulate) and prints what `beamid run DECK` prints: one summary line (the
!! deck's path and what the run found) and 'wrote PATH' per file written
!! (nothing with --quiet). Exit codes (beamid_status
!! exit_code): 0 success, 2 bad input, 3 numerical failure, 4 an output file
!! cannot be written, 5 internal error; every problem found goes to standard
!! error, one per line, naming the deck, the group and the variable.
program beamid_batch
    use, intrinsic :: iso_fortran_env, only: error_unit, output_unit
    use beamid_status, only: status_t, STATUS_OK, exit_code, EXIT_BAD_INPUT
    use beamid_deck_run, only: deck_run_t, deck_run_open, deck_run_task
    use beamid_tasks, only: deck_warnings
    implicit none

    character(len=*), parameter :: VERSION = '0.1.0'
    character(len=:), allocatable :: arg, path, written, summary
    type(deck_run_t) :: run
    type(status_t) :: stat
    logical :: quiet
    integer :: i, n, start, nl

    quiet = .false.
    path = ''
    do i = 1, command_argument_count()
        call get_command_argument(i, length=n)
        allocate (character(len=n) :: arg)
        call get_command_argument(i, arg)
        select case (arg)
        case ('-h', '--help')
            call usage(output_unit)
            stop
        case ('--version')
            write (output_unit, '(a)') 'beamid-batch '//VERSION
            stop
        case ('-q', '--quiet')
            quiet = .true.
        case default
            if (len(path) > 0 .or. (len(arg) > 1 .and. arg(1:1) == '-')) then
                call usage(error_unit)
                stop EXIT_BAD_INPUT, quiet=.true.
            end if
            path = arg
        end select
        deallocate (arg)
    end do
    if (len(path) == 0) then
        call usage(error_unit)
        stop EXIT_BAD_INPUT, quiet=.true.
    end if

    call deck_run_open(path, run, stat)
    if (stat%code == STATUS_OK) call deck_run_task(run, '', written, summary, stat)
    if (stat%code /= STATUS_OK) then
        if (allocated(run%deck%errors)) then
            if (len(run%deck%errors) > 0) then
                call report(run%deck%errors)
                stop exit_code(stat%code), quiet=.true.
            end if
        end if
        call report(trim(stat%message))
        stop exit_code(stat%code), quiet=.true.
    end if
    call report(deck_warnings(run%deck), 'warning')
    if (quiet) stop
    write (output_unit, '(a)') summary
    start = 1
    do while (start <= len(written))
        nl = index(written(start:), new_line('a'))
        if (nl == 0) nl = len(written) - start + 2
        write (output_unit, '(a)') 'wrote '//written(start:start + nl - 2)
        start = start + nl
    end do

contains

    !> One line 'beamid-batch: error: ...' per line of text.
    !> Each line of text to stderr as 'beamid-batch: <what>: line' (what:
    !! 'error' unless given).
    subroutine report(text, what)
        character(len=*), intent(in) :: text
        character(len=*), intent(in), optional :: what
        character(len=:), allocatable :: label
        integer :: start, nl
        label = 'error'
        if (present(what)) label = what
        start = 1
        do while (start <= len(text))
            nl = index(text(start:), new_line('a'))
            if (nl == 0) nl = len(text) - start + 2
            write (error_unit, '(a)') 'beamid-batch: '//label//': '//text(start:start + nl - 2)
            start = start + nl
        end do
    end subroutine report

    subroutine usage(unit)
        integer, intent(in) :: unit
        write (unit, '(a)') 'usage: beamid-batch [--quiet] [--version] DECK'
        write (unit, '(a)') 'Runs a beamid namelist deck (docs/decks.md): static decks write '// &
            '<output>_summary.csv and <output>_shape.csv next to the deck;'
        write (unit, '(a)') 'fe decks _summary.csv and _nodes.csv or _modes.csv; estimation '// &
            'decks (fit, compare, diagnose, improve, identify) _estimates.csv,'
        write (unit, '(a)') '_covariance.csv, _residuals.csv, _ranking.csv (diagnose, improve), '// &
            '_compare.csv (compare) and _ladder.csv (improve);'
        write (unit, '(a)') '_identify.csv (identify); dynamic decks (task simulate) '// &
            '_history.csv. Prints a summary line and the files written'
        write (unit, '(a)') '(as beamid run DECK; --quiet: nothing).'
        write (unit, '(a)') 'Exit codes: 0 ok, 2 bad input, 3 numerical failure, 4 output '// &
            'not written, 5 internal error.'
    end subroutine usage
end program beamid_batch
