!> The registry of experiment families: what each family is and which
!! experiment kinds it takes, in the order the problem evaluates them.
!!
!! A new family is one module extending experiment_family_t
!! (beamid_family) and one `call register` line below, a row of the
!! registry's table: its name, its FAM_* code, its experiment kinds (EXP_*)
!! with their words, whether its rows are records in time and where a spec
!! holds its mesh (plus its use line and its line in meson.build); the
!! problem (beamid_problem), the chain's checks and the diagnosis ask the
!! families, never a kind code.
module beamid_families
    use beamid_family, only: experiment_family_t, family_slot_t, family_identity_t, &
                             KIND_LABEL_LEN, EXP_TIP, EXP_WIRE, EXP_RELEASE, EXP_MODAL, EV_NEPB
    use beamid_observations, only: FAM_STATIC, FAM_RELEASE, FAM_MODAL
    use beamid_status, only: fmt_int
    use beamid_static_experiments, only: static_experiments_t
    use beamid_dynamic_experiments, only: dynamic_experiments_t
    use beamid_modal_experiments, only: modal_experiments_t
    implicit none
    private

    public :: registered_families, family_of_kind, kind_timed, kind_mesh_key, kinds_expected
    public :: has_mesh

    !> Experiment kinds are searched up to this code for kinds_expected.
    integer, parameter :: KIND_SEARCH = 64

contains

    !> One empty instance of every registered family, in evaluation order.
    subroutine registered_families(fams)
        type(family_slot_t), allocatable, intent(out) :: fams(:)
        allocate (fams(0))
        call register(fams, static_experiments_t(), &
                      family_identity_t(name='static', code=FAM_STATIC, kinds=[EXP_TIP, EXP_WIRE], &
                                        labels=[character(len=KIND_LABEL_LEN) :: 'tip load', &
                                                'wire']))
        call register(fams, dynamic_experiments_t(), &
                      family_identity_t(name='release', code=FAM_RELEASE, kinds=[EXP_RELEASE], &
                                        labels=[character(len=KIND_LABEL_LEN) :: 'release'], &
                                        timed=.true., mesh_key=EV_NEPB))
        call register(fams, modal_experiments_t(), &
                      family_identity_t(name='modal', code=FAM_MODAL, kinds=[EXP_MODAL], &
                                        labels=[character(len=KIND_LABEL_LEN) :: 'modal'], &
                                        mesh_key=EV_NEPB))
    end subroutine registered_families

    !> Append a family: an empty instance of its type and what it is.
    subroutine register(fams, proto, id)
        type(family_slot_t), allocatable, intent(inout) :: fams(:)
        class(experiment_family_t), intent(in) :: proto
        type(family_identity_t), intent(in) :: id
        type(family_slot_t), allocatable :: more(:)
        integer :: i
        allocate (more(size(fams) + 1))
        do i = 1, size(fams)
            call move_alloc(fams(i)%item, more(i)%item)
        end do
        allocate (more(size(more))%item, source=proto)
        call more(size(more))%item%identify(id)
        call move_alloc(more, fams)
    end subroutine register

    !> The index in `fams` of the family that takes experiments of `kind`
    !! (0: none does).
    pure integer function family_of_kind(fams, kind) result(f)
        type(family_slot_t), intent(in) :: fams(:)
        integer, intent(in) :: kind
        do f = 1, size(fams)
            if (fams(f)%item%claims(kind)) return
        end do
        f = 0
    end function family_of_kind

    !> Whether experiments of `kind` are records in time (false for an
    !! unknown kind).
    logical function kind_timed(kind)
        integer, intent(in) :: kind
        type(family_slot_t), allocatable :: fams(:)
        integer :: f
        call registered_families(fams)
        f = family_of_kind(fams, kind)
        kind_timed = .false.
        if (f > 0) kind_timed = fams(f)%item%timed()
    end function kind_timed

    !> The key of a spec (EV_*) that holds the elements per beam of an
    !! experiment of `kind` (0: no mesh to refine).
    integer function kind_mesh_key(kind)
        integer, intent(in) :: kind
        type(family_slot_t), allocatable :: fams(:)
        integer :: f
        call registered_families(fams)
        f = family_of_kind(fams, kind)
        kind_mesh_key = 0
        if (f > 0) kind_mesh_key = fams(f)%item%mesh_key()
    end function kind_mesh_key

    !> Whether an experiment of the kinds `exp_kind` has a mesh of its own
    !! (its family's mesh_key: a release, a modal test) that the mesh test
    !! can refine.
    logical function has_mesh(exp_kind)
        integer, intent(in) :: exp_kind(:)
        integer :: e
        has_mesh = .false.
        do e = 1, size(exp_kind)
            if (kind_mesh_key(exp_kind(e)) > 0) has_mesh = .true.
        end do
    end function has_mesh

    !> The experiment kinds the families take, in words: '1 (tip load),
    !! 2 (wire) or 3 (release)'.
    function kinds_expected() result(text)
        character(len=:), allocatable :: text
        type(family_slot_t), allocatable :: fams(:)
        character(len=:), allocatable :: last
        integer :: k, f
        call registered_families(fams)
        text = ''
        last = ''
        do k = 1, KIND_SEARCH
            f = family_of_kind(fams, k)
            if (f == 0) cycle
            if (len(last) > 0) then
                if (len(text) > 0) text = text//', '
                text = text//last
            end if
            last = fmt_int(k)//' ('//fams(f)%item%kind_label(k)//')'
        end do
        if (len(text) > 0) then
            text = text//' or '//last
        else
            text = last
        end if
    end function kinds_expected
end module beamid_families
