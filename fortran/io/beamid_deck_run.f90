!> A run of a deck, read once: the deck as read (its measurement files with
!! it), and for an estimation deck the ladder or the identify stages its
!! task ran, from which its files are written. The caller holds the run
!! (beamid-batch a local variable, the Python front a handle of the binding
!! owned by a Python object): no state is kept here, nothing is found again
!! by path (issue 25, the fronts).
!!
!! A run of an estimation deck goes in steps, so that a front can show
!! progress and read every rung before the files are written:
!! deck_run_start (the fit), deck_run_step (a rung per call until done),
!! deck_run_write (the files, all or none, the bytes beamid-batch writes).
!! deck_run_task runs any deck's task in one call, as beamid-batch does.
!!
!! The deck is never copied (gfortran 12's intrinsic assignment of a type
!! with deferred-length character array components, as deck_t's, is wrong:
!! beamid_deck copy_measurements): a task or an output prefix other than the
!! deck's own is set on the deck in place for the call that needs it.
module beamid_deck_run
    use beamid_status, only: status_t, STATUS_OK, ERR_INPUT, set_status, fmt_int
    use beamid_deck, only: deck_t, read_deck, deck_set_task
    use beamid_ladder, only: ladder_t, rung_t, ladder_step
    use beamid_tasks, only: run_task, deck_ladder_start, deck_stage_start, name_experiment
    implicit none
    private

    public :: deck_run_t, deck_run_open, deck_run_task, deck_run_start, deck_run_step, &
              deck_run_write

    !> A deck read once and what its task ran.
    type :: deck_run_t
        !> the deck as read (its task and output set in place while a call
        !! runs it as another task or writes elsewhere; restored after)
        type(deck_t) :: deck
        !> the deck's own task and output prefix, as read
        character(len=:), allocatable :: task, output
        !> the task the ladder or the stages of deck_run_start ran
        character(len=:), allocatable :: task_run
        !> the ladder of the task run by deck_run_start and deck_run_step
        type(ladder_t) :: lad
        !> the stages of an identify deck fitted so far
        type(rung_t), allocatable :: staged(:)
        !> a ladder (or a stage) was started on this deck
        logical :: started = .false.
    end type deck_run_t

contains

    !> Read and validate the deck at path (and the measurement files it names)
    !! into run; the problems found are in run%deck%errors, one per line.
    subroutine deck_run_open(path, run, stat, fit_keys)
        character(len=*), intent(in) :: path
        type(deck_run_t), intent(out) :: run
        type(status_t), intent(inout) :: stat
        !> items of &fit given apart (beamid_deck read_deck: the command
        !! line's measurement chain options), which replace the deck's
        character(len=*), intent(in), optional :: fit_keys
        call read_deck(path, run%deck, stat, fit_keys)
        allocate (run%staged(0))
        run%task = ''
        run%output = ''
        if (allocated(run%deck%task)) run%task = run%deck%task
        if (allocated(run%deck%output)) run%output = run%deck%output
    end subroutine deck_run_open

    !> Set the deck of run to `task` (blank: its own; an estimation task for
    !! an estimation deck only, beamid_deck deck_set_task), its output to
    !! its own.
    subroutine as_task(run, task, stat)
        type(deck_run_t), intent(inout) :: run
        character(len=*), intent(in) :: task
        type(status_t), intent(inout) :: stat
        run%deck%task = run%task
        run%deck%output = run%output
        call deck_set_task(run%deck, task, stat)
    end subroutine as_task

    !> The deck of run as read again (its own task and output).
    subroutine as_read(run)
        type(deck_run_t), intent(inout) :: run
        run%deck%task = run%task
        run%deck%output = run%output
    end subroutine as_read

    !> Run the deck's task (or `task`) and write its files, as beamid-batch
    !! (beamid_tasks run_task): the files written, one per line, and the
    !! summary line beamid-batch prints.
    subroutine deck_run_task(run, task, written, summary, stat)
        type(deck_run_t), intent(inout) :: run
        character(len=*), intent(in) :: task
        character(len=:), allocatable, intent(out) :: written, summary
        type(status_t), intent(inout) :: stat
        written = ''
        summary = ''
        call as_task(run, task, stat)
        if (stat%code == STATUS_OK) call run_task(run%deck, written, stat, summary=summary)
        call as_read(run)
    end subroutine deck_run_task

    !> Start the ladder of an estimation deck run as `task` (blank: its own),
    !! as beamid-batch runs it (beamid_tasks deck_ladder_start: the fit,
    !! undiagnosed for fit and compare); of an identify deck the fit of
    !! `stage` (1-based, in order) from the stages fitted before
    !! (deck_stage_start). Stage 1, or another task, starts afresh.
    subroutine deck_run_start(run, task, stage, stat)
        type(deck_run_t), intent(inout) :: run
        character(len=*), intent(in) :: task
        integer, intent(in) :: stage
        type(status_t), intent(inout) :: stat
        call as_task(run, task, stat)
        if (stage <= 1 .or. .not. run%started) then
            run%staged = [rung_t ::]
        else if (run%task_run /= run%deck%task) then
            run%staged = [rung_t ::]
        end if
        run%lad%done = .true.
        run%lad%n = 0
        run%started = .false.
        if (stat%code == STATUS_OK .and. max(stage, 1) /= size(run%staged) + 1) &
            call set_status(stat, ERR_INPUT, 'stage', fmt_int(stage)//', expected '// &
                            fmt_int(size(run%staged) + 1)//' (the stages in order)')
        if (stat%code == STATUS_OK) then
            if (run%deck%task == 'identify') then
                call deck_stage_start(run%deck, run%staged, run%lad, stat)
                if (stat%code == STATUS_OK) run%staged = [run%staged, run%lad%rungs(1)]
            else
                call deck_ladder_start(run%deck, run%lad, stat)
            end if
        end if
        if (stat%code == STATUS_OK) then
            run%task_run = run%deck%task
            run%started = .true.
        end if
        call as_read(run)
    end subroutine deck_run_start

    !> One rung of the run's ladder (beamid_ladder ladder_step); a failure
    !! names the experiment and the deck, as beamid-batch.
    subroutine deck_run_step(run, stat)
        type(deck_run_t), intent(inout) :: run
        type(status_t), intent(inout) :: stat
        if (.not. run%started) then
            call set_status(stat, ERR_INPUT, 'ladder', 'no ladder started on '// &
                            run%deck%path//' (deck_run_start first)')
            return
        end if
        call ladder_step(run%lad, stat)
        if (stat%code /= STATUS_OK .and. allocated(run%deck%exp_names)) &
            call name_experiment(run%deck, stat)
    end subroutine deck_run_step

    !> Write the files of the run's task (beamid_tasks run_task: all or none,
    !! the bytes beamid-batch writes) from its ended ladder or its stages;
    !! `output`: the output prefix (blank: the deck's).
    subroutine deck_run_write(run, output, written, summary, stat)
        type(deck_run_t), intent(inout) :: run
        character(len=*), intent(in) :: output
        character(len=:), allocatable, intent(out) :: written, summary
        type(status_t), intent(inout) :: stat
        written = ''
        summary = ''
        if (.not. run%started .or. .not. run%lad%done .or. run%lad%n < 1) then
            call set_status(stat, ERR_INPUT, 'ladder', 'no ended ladder of '//run%deck%path// &
                            ' (deck_run_start and deck_run_step first)')
            return
        end if
        call as_task(run, run%task_run, stat)
        if (len_trim(output) > 0) run%deck%output = trim(output)
        if (stat%code /= STATUS_OK) then
            continue
        else if (run%deck%task == 'identify') then
            if (size(run%staged) /= size(run%deck%stages)) then
                call set_status(stat, ERR_INPUT, 'identify', fmt_int(size(run%staged))// &
                                ' of '//fmt_int(size(run%deck%stages))//' stages fitted, '// &
                                'expected all (deck_run_start each stage first)')
            else
                call run_task(run%deck, written, stat, run%staged, summary)
            end if
        else
            call run_task(run%deck, written, stat, run%lad%rungs(:run%lad%n), summary)
        end if
        call as_read(run)
    end subroutine deck_run_write
end module beamid_deck_run
