!> The binding's one handle table (no f2py entry here: a module of the core
!! library that the f2py modules of fortran/api share): the runs the fronts
!! hold, a deck's run (beamid_deck_run, beamid_api_deck) or a problem's
!! improve ladder (beamid_ladder, beamid_api_estimation). A run is opened
!! into a free slot whose number is its handle, found by that handle only,
!! and freed by the caller that owns the handle (the Python objects
!! beamid._core.DeckHandle and beamid._core_estimation.LadderHandle), so two
!! runs (two threads' improves, two handles of one deck) never meet. Slots
!! move, never copy (a deck_t cannot be assigned: beamid_deck_run).
module beamid_api_runs
    use, intrinsic :: iso_c_binding, only: c_int
    use beamid_status, only: status_t, status_out, set_status, fmt_int, ERR_INPUT
    use beamid_deck_run, only: deck_run_t
    use beamid_ladder, only: ladder_t
    implicit none
    private

    public :: run_slot_t, runs, RUN_DECK, RUN_LADDER, run_open, run_close, runs_held, run_ok

    !> What a slot holds.
    integer, parameter :: RUN_DECK = 1, RUN_LADDER = 2

    !> A slot of the table: a deck's run or a problem's ladder (neither: free).
    type :: run_slot_t
        type(deck_run_t), allocatable :: deck
        type(ladder_t), allocatable :: lad
    end type run_slot_t

    !> The runs opened and not yet closed: runs(h) is the run of handle h.
    type(run_slot_t), allocatable, save :: runs(:)

contains

    !> Does slot h hold a run of `kind`?
    logical function held(h, kind)
        integer, intent(in) :: h, kind
        held = .false.
        if (.not. allocated(runs)) return
        if (h < 1 .or. h > size(runs)) return
        select case (kind)
        case (RUN_DECK)
            held = allocated(runs(h)%deck)
        case (RUN_LADDER)
            held = allocated(runs(h)%lad)
        end select
    end function held

    !> A new run of `kind` (RUN_DECK, RUN_LADDER), allocated in the first
    !! free slot (the table grows when none is free): h its handle.
    subroutine run_open(kind, h)
        integer, intent(in) :: kind
        integer, intent(out) :: h
        type(run_slot_t), allocatable :: grown(:)
        integer :: i
        if (.not. allocated(runs)) allocate (runs(0))
        h = size(runs) + 1
        do i = 1, size(runs)
            if (held(i, RUN_DECK) .or. held(i, RUN_LADDER)) cycle
            h = i
            exit
        end do
        if (h > size(runs)) then
            allocate (grown(2*size(runs) + 1))
            do i = 1, size(runs)
                call move_alloc(runs(i)%deck, grown(i)%deck)
                call move_alloc(runs(i)%lad, grown(i)%lad)
            end do
            call move_alloc(grown, runs)
        end if
        if (kind == RUN_DECK) allocate (runs(h)%deck)
        if (kind == RUN_LADDER) allocate (runs(h)%lad)
    end subroutine run_open

    !> Release the run of `kind` under handle h (none held: nothing happens).
    subroutine run_close(h, kind)
        integer, intent(in) :: h, kind
        if (.not. held(h, kind)) return
        if (kind == RUN_DECK) deallocate (runs(h)%deck)
        if (kind == RUN_LADDER) deallocate (runs(h)%lad)
    end subroutine run_close

    !> The number of runs of `kind` held (handles not yet closed).
    integer function runs_held(kind) result(n)
        integer, intent(in) :: kind
        integer :: h
        n = 0
        if (.not. allocated(runs)) return
        do h = 1, size(runs)
            if (held(h, kind)) n = n + 1
        end do
    end function runs_held

    !> Is `handle` a run of `kind`? Else ERR_INPUT naming the handle and what
    !! it should be (an open deck or ladder, the entry that opens it).
    logical function run_ok(handle, kind, code, message)
        integer(c_int), intent(in) :: handle
        integer, intent(in) :: kind
        integer(c_int), intent(out) :: code
        character(len=*), intent(out) :: message
        type(status_t) :: stat
        character(len=:), allocatable :: what
        run_ok = held(int(handle), kind)
        if (kind == RUN_DECK) then
            what = 'an open deck (api_deck_open, not closed)'
        else
            what = 'an open ladder (api_ladder_open, not closed)'
        end if
        if (.not. run_ok) call set_status(stat, ERR_INPUT, 'handle', fmt_int(int(handle))// &
                                          ', expected the handle of '//what)
        call status_out(stat, code, message)
    end function run_ok
end module beamid_api_runs
