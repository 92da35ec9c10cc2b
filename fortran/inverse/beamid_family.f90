!> An experiment family: the abstract type every family of the inverse
!! problem extends (issue 25, "experiment families, an open list").
!!
!! A family owns its experiments and the data rows they predict: it builds
!! itself from its experiments' specs and its rows (`build`, on a
!! family_input_t), evaluates the predictions and Jacobian of all its rows
!! at once (`evaluate`, the residual_model_t interface: one type-bound call
!! per evaluation, never one per row), proposes probe rows for a diagnosis
!! (`probe`), tells which observation kinds it can produce (`observes`, from
!! the families column of beamid_observations) and which spec keys it takes
!! (`accepts`, from SPEC_KEYS).
!!
!! What a family is (its name, code, experiment kinds and their words,
!! whether its rows are records in time, where its mesh lives in a spec) is
!! data of the base type, set once when the family is registered
!! (beamid_families, one `call register` line a family, through `identify`)
!! and read through the accessors below, which no family overrides; `setup`
!! builds a family and keeps that identity. The problem (beamid_problem)
!! holds a list of families (family_slot_t); a new family is one module
!! extending this type plus its line in the registry (docs/development.md,
!! "Adding an experiment family").
!!
!! The spec of an experiment is an experiment_spec_t: a value for every key
!! of the one key table SPEC_KEYS, read and written by key (the EV_*
!! identifiers, each the index of its key in SPEC_KEYS) or by name through
!! its type-bound procedures; how the values are stored is the type's own.
module beamid_family
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_INPUT, fmt_int
    use beamid_arclength, only: LOAD_TIP, LOAD_WIRE
    use beamid_estimation, only: residual_model_t
    use beamid_observations, only: observation_t, KINDS, FAM_STATIC, FAM_RELEASE, FAM_MODAL
    implicit none
    private

    public :: experiment_family_t, family_slot_t, spec_key_t, spec_key_index, spec_keys_text

    !> Experiment kinds: the static loads of beamid_arclength, and a release.
    integer, parameter, public :: EXP_TIP = LOAD_TIP, EXP_WIRE = LOAD_WIRE, EXP_RELEASE = 3
    !> A modal test about the equilibrium under a tip load (issue 27,
    !! beamid_modal_experiments).
    integer, parameter, public :: EXP_MODAL = 4
    !> The keys of an experiment's spec (experiment_spec_t): each the index
    !! of its entry in SPEC_KEYS.
    integer, parameter, public :: EV_FX = 1, EV_FY = 2, EV_MOMENT = 3, EV_WIRE_LENGTH = 4, &
                                  EV_NEPB = 5, EV_GAIN = 6, EV_METHOD = 7, EV_LAW = 8, &
                                  EV_RTOL = 9, EV_DT = 10, EV_VSLIP = 11, EV_FD = 12
    !! (EV_FD = 1: central-difference sensitivities, the benchmark baseline;
    !! 2: forward sensitivities at the experiment's tolerance at every fit
    !! iteration, no rough Jacobian: fit(..., jacobian="exact"))
    !> The measurement chain of an experiment: EV_T0 (1: its record has a
    !! clock offset, timed families only), EV_BIAS and EV_SCALE (bit q - 1
    !! set: the channel of entry q of the observation list has a bias, a scale).
    integer, parameter, public :: EV_T0 = 13, EV_BIAS = 14, EV_SCALE = 15
    !> The rows' treatment (beamid_chain_fit): EV_LOSS the loss of the
    !! experiment's rows (0 linear, 1 Huber, 2 Cauchy), EV_BURNIN a time
    !! before which its rows are predicted but not fitted (0: none), EV_SIGEST
    !! the channels (bit q - 1: entry q of the observation list) whose sigma
    !! is estimated from the residuals.
    integer, parameter, public :: EV_LOSS = 16, EV_BURNIN = 17, EV_SIGEST = 18
    !> EV_V0 (1: a release's initial velocity v0 is a nuisance parameter of
    !! the measurement chain: the chain starts from its static shape with the
    !! velocity field v0 q / w_tip(q), q the static displacement).
    integer, parameter, public :: EV_V0 = 19
    !> The number of keys of SPEC_KEYS.
    integer, parameter, public :: NEXPVAL = 19

    !> A named key of an experiment's spec: its name (the deck's), its
    !! identifier (EV_*: its index in SPEC_KEYS), the families that accept it (FAM_* bits
    !! of beamid_observations' families column; ALL_FAMILIES: the measurement
    !! chain's keys, which every family accepts and the problem checks) and
    !! the value an experiment of such a family takes when the key is not
    !! given.
    type :: spec_key_t
        character(len=17) :: name = ''
        integer :: key = 0
        integer :: families = 0
        real(dp) :: default = 0.0_dp
        character(len=80) :: about = ''
    end type spec_key_t

    integer, parameter, public :: ALL_FAMILIES = -1
    !> The longest words of an experiment kind (kind_label).
    integer, parameter, public :: KIND_LABEL_LEN = 16
    integer, parameter :: BOTH = FAM_STATIC + FAM_RELEASE + FAM_MODAL
    !> the finite element families: a mesh and central-difference columns
    integer, parameter :: FE_FAMS = FAM_RELEASE + FAM_MODAL

    !> The one key table of experiment specs (the deck's names; codes for
    !! integrator, friction and loss as the deck reader gives them).
    type(spec_key_t), parameter, public :: SPEC_KEYS(NEXPVAL) = [ &
        spec_key_t('fx', EV_FX, BOTH, 0.0_dp, 'tip force along x (N)'), &
        spec_key_t('fy', EV_FY, BOTH, 0.0_dp, 'tip force along y (N)'), &
        spec_key_t('moment', EV_MOMENT, BOTH, 0.0_dp, 'tip moment (N m)'), &
        spec_key_t('wire_length', EV_WIRE_LENGTH, FAM_STATIC + FAM_MODAL, 0.0_dp, &
                   'radial wire length (m; kind 2)'), &
        spec_key_t('elements_per_beam', EV_NEPB, FE_FAMS, 4.0_dp, &
                   'finite elements per beam'), &
        spec_key_t('motor_gain', EV_GAIN, FAM_RELEASE, 0.0_dp, 'motor gain (0: no motor)'), &
        spec_key_t('integrator', EV_METHOD, FAM_RELEASE, 0.0_dp, &
                   'integrator code (0 rk4, 1 implicit)'), &
        spec_key_t('friction', EV_LAW, FAM_RELEASE, 0.0_dp, &
                   'friction law code (0 sign, 1 smooth, 2 sign_literal)'), &
        spec_key_t('rtol', EV_RTOL, FAM_RELEASE, 0.0_dp, 'relative tolerance (0: default)'), &
        spec_key_t('dt', EV_DT, FAM_RELEASE, 0.0_dp, 'rk4 time step (s; 0: default)'), &
        spec_key_t('v_slip', EV_VSLIP, FAM_RELEASE, 0.0_dp, &
                   'smooth friction slip speed (m/s; 0: 1e-4)'), &
        spec_key_t('fd', EV_FD, FE_FAMS, 0.0_dp, &
                   'sensitivities (0 rough, 1 central differences, 2 exact)'), &
        spec_key_t('t0', EV_T0, ALL_FAMILIES, 0.0_dp, '1: the record has a clock offset'), &
        spec_key_t('bias', EV_BIAS, ALL_FAMILIES, 0.0_dp, 'channel mask of biases'), &
        spec_key_t('scale', EV_SCALE, ALL_FAMILIES, 0.0_dp, 'channel mask of scales'), &
        spec_key_t('loss', EV_LOSS, ALL_FAMILIES, 0.0_dp, &
                   'loss code (0 linear, 1 huber, 2 cauchy)'), &
        spec_key_t('burn_in', EV_BURNIN, ALL_FAMILIES, 0.0_dp, &
                   'time before which rows are not fitted (s)'), &
        spec_key_t('sigma_est', EV_SIGEST, ALL_FAMILIES, 0.0_dp, &
                   'channel mask of estimated sigmas'), &
        spec_key_t('v0', EV_V0, ALL_FAMILIES, 0.0_dp, &
                   '1: the release''s initial tip normal velocity is fitted')]

    !> One experiment's spec: the value of every key of SPEC_KEYS (a key not
    !! set holds 0). Read and written by key (`get`, `get_int`, `set`, with
    !! an EV_* identifier) or by the key's name (`value_of`, `set_named`);
    !! nothing outside this type knows how the values are stored.
    type, public :: experiment_spec_t
        real(dp), private :: v(NEXPVAL) = 0.0_dp
    contains
        procedure :: get => spec_get
        procedure :: get_int => spec_get_int
        procedure :: set => spec_set
        procedure :: value_of => spec_value_of
        procedure :: set_named => spec_set_named
        procedure :: chain_asked => spec_chain_asked
        procedure :: clear_treatment => spec_clear_treatment
        procedure :: take_chain => spec_take_chain
    end type experiment_spec_t

    !> What a family is, a row of the registry (beamid_families): its name
    !! in messages, its code in the families column of beamid_observations,
    !! the experiment kinds (EXP_*) it takes and their words, whether its rows
    !! are records in time (a row has t; a clock offset and a burn-in make
    !! sense) and the key of a spec (EV_*) that holds its elements per beam
    !! (0: no mesh to refine).
    type, public :: family_identity_t
        character(len=:), allocatable :: name
        integer :: code = 0
        integer, allocatable :: kinds(:)
        character(len=KIND_LABEL_LEN), allocatable :: labels(:)
        logical :: timed = .false.
        integer :: mesh_key = 0
    end type family_identity_t

    !> What a family's build reads: the model's number of beams, the kind
    !! (EXP_*) and spec of each of its experiments, and its data rows
    !! (row_exp local experiment numbers 1..size(kinds), times, observations)
    !! with the static solver's tolerance (0: default).
    type, public :: family_input_t
        integer :: nbeams = 0
        integer, allocatable :: kinds(:)
        type(experiment_spec_t), allocatable :: specs(:)
        integer, allocatable :: row_exp(:)
        real(dp), allocatable :: row_t(:)
        type(observation_t), allocatable :: row_obs(:)
        real(dp) :: tol = 0.0_dp
    end type family_input_t

    !> One family of experiments and the data rows they predict.
    type, abstract, extends(residual_model_t) :: experiment_family_t
        !> what the family is (set by identify at registration)
        type(family_identity_t), private :: id
        !> the model's number of beams, the local experiment and the
        !! observation of each of the family's rows
        integer :: nbeams = 0
        integer, allocatable :: row_exp(:)
        type(observation_t), allocatable :: row_obs(:)
        !> the problem's data rows of this family, in the family's row order
        integer, allocatable :: rows(:)
        !> the problem's number of each of the family's experiments
        integer, allocatable :: exp_ids(:)
        !> timed families: the model time at each experiment's record zero
        !! (its clock offset t0, set by the problem before evaluate), and on
        !! request (want_rates) d prediction / d t of every row
        real(dp), allocatable :: shift(:)
        logical :: want_rates = .false.
        real(dp), allocatable :: row_rate(:)
        !> releases: each experiment's initial tip normal velocity (the chain
        !! nuisance v0, set by the problem before evaluate; 0: at rest), whether
        !! its column is asked (v0_fit), and then d prediction / d v0 of every
        !! row (row_dv0)
        real(dp), allocatable :: v0(:)
        logical, allocatable :: v0_fit(:)
        real(dp), allocatable :: row_dv0(:)
    contains
        procedure(build_if), deferred :: build
        procedure :: probe => no_probe
        procedure :: probe_model => no_probe_model
        procedure, non_overridable :: identify
        procedure, non_overridable :: setup
        procedure, non_overridable :: name
        procedure, non_overridable :: claims
        procedure, non_overridable :: kind_label
        procedure, non_overridable :: kind_codes
        procedure, non_overridable :: timed
        procedure, non_overridable :: family_code
        procedure, non_overridable :: mesh_key
        procedure, non_overridable :: exp_rows
        procedure, non_overridable :: observes
        procedure, non_overridable :: accepts
    end type experiment_family_t

    !> A slot of the problem's list of families.
    type :: family_slot_t
        class(experiment_family_t), allocatable :: item
    end type family_slot_t

    abstract interface
        !> Build from the experiments' kinds and specs and the
        !! family's rows (beamid_problem calls it through setup).
        subroutine build_if(self, input, stat)
            import :: experiment_family_t, family_input_t, status_t
            class(experiment_family_t), intent(inout) :: self
            type(family_input_t), intent(in) :: input
            type(status_t), intent(inout) :: stat
        end subroutine build_if
    end interface

contains

    !> Set what the family is (at registration, beamid_families).
    pure subroutine identify(self, id)
        class(experiment_family_t), intent(inout) :: self
        type(family_identity_t), intent(in) :: id
        self%id = id
    end subroutine identify

    !> Build the family on its experiments and rows (build, which may set
    !! the family up afresh: what the family is stays as registered; a family
    !! with a mesh is refused an experiment with less than one element per
    !! beam before its build), then
    !! take the problem's numbers of its rows and experiments and, for the
    !! evaluations, the input's beams, local experiments and observations.
    subroutine setup(self, input, rows, exp_ids, stat)
        class(experiment_family_t), intent(inout) :: self
        type(family_input_t), intent(in) :: input
        integer, intent(in) :: rows(:), exp_ids(:)
        type(status_t), intent(inout) :: stat
        type(family_identity_t) :: id
        integer :: e, nepb
        ! a family with a mesh: at least one element per beam in each experiment
        if (self%id%mesh_key > 0) then
            do e = 1, size(input%kinds)
                nepb = input%specs(e)%get_int(self%id%mesh_key)
                if (nepb < 1) then
                    call set_status(stat, ERR_INPUT, self%name()//' experiments', 'experiment '// &
                                    fmt_int(e)//': '//trim(SPEC_KEYS(self%id%mesh_key)%name)// &
                                    ' = '//fmt_int(nepb)//', expected >= 1')
                    return
                end if
            end do
        end if
        id = self%id
        call self%build(input, stat)
        self%id = id
        if (stat%code /= 0) return
        self%nbeams = input%nbeams
        self%row_exp = input%row_exp
        self%row_obs = input%row_obs
        self%rows = rows
        self%exp_ids = exp_ids
    end subroutine setup

    !> The family's name in messages ('static', 'release').
    pure function name(self) result(text)
        class(experiment_family_t), intent(in) :: self
        character(len=:), allocatable :: text
        text = ''
        if (allocated(self%id%name)) text = self%id%name
    end function name

    !> Whether experiments of this kind (EXP_*) belong to the family.
    pure logical function claims(self, kind)
        class(experiment_family_t), intent(in) :: self
        integer, intent(in) :: kind
        claims = .false.
        if (allocated(self%id%kinds)) claims = any(self%id%kinds == kind)
    end function claims

    !> The words for an experiment kind of the family ('tip load'; '' for a
    !! kind it does not take).
    pure function kind_codes(self) result(codes)
        !! The experiment kinds (EXP_*) the family takes, as registered.
        class(experiment_family_t), intent(in) :: self
        integer, allocatable :: codes(:)
        allocate (codes(0))
        if (allocated(self%id%kinds)) codes = self%id%kinds
    end function kind_codes

    pure function kind_label(self, kind) result(text)
        class(experiment_family_t), intent(in) :: self
        integer, intent(in) :: kind
        character(len=:), allocatable :: text
        integer :: k
        text = ''
        if (.not. allocated(self%id%kinds)) return
        k = findloc(self%id%kinds, kind, 1)
        if (k > 0) text = trim(self%id%labels(k))
    end function kind_label

    !> Whether the family's rows are records in time.
    pure logical function timed(self)
        class(experiment_family_t), intent(in) :: self
        timed = self%id%timed
    end function timed

    !> The family's code in the families column of beamid_observations.
    pure integer function family_code(self)
        class(experiment_family_t), intent(in) :: self
        family_code = self%id%code
    end function family_code

    !> The key of a spec (EV_*) holding the family's elements per beam, 0
    !! when it has no mesh to refine.
    pure integer function mesh_key(self)
        class(experiment_family_t), intent(in) :: self
        mesh_key = self%id%mesh_key
    end function mesh_key

    !> The family's rows (its own numbering) of its local experiment e.
    pure function exp_rows(self, e) result(r)
        class(experiment_family_t), intent(in) :: self
        integer, intent(in) :: e
        integer, allocatable :: r(:)
        integer :: i
        r = pack([(i, i=1, size(self%row_exp))], self%row_exp == e)
    end function exp_rows

    !> The family's probe rows for a diagnosis, from the sigmas of its data
    !! rows: the family's (local) experiment number, the observation kind
    !! and the sigma of each. None by default.
    subroutine no_probe(self, sigma, plocal, pq, psig)
        class(experiment_family_t), intent(in) :: self
        real(dp), intent(in) :: sigma(:)
        integer, allocatable, intent(out) :: plocal(:), pq(:)
        real(dp), allocatable, intent(out) :: psig(:)
        allocate (plocal(0), pq(0), psig(0))
        if (.false.) plocal = [size(self%exp_ids), size(sigma)]
    end subroutine no_probe

    !> A model of the family's probe rows (plocal its local experiments, pq
    !! the kinds), or none (not allocated) by default.
    subroutine no_probe_model(self, plocal, pq, tol, model, stat)
        class(experiment_family_t), intent(in) :: self
        integer, intent(in) :: plocal(:), pq(:)
        real(dp), intent(in) :: tol
        class(residual_model_t), allocatable, intent(inout) :: model
        type(status_t), intent(inout) :: stat
        if (allocated(model)) deallocate (model)
        if (.false.) stat%code = size(plocal) + size(pq) + size(self%exp_ids) + int(tol)
    end subroutine no_probe_model

    !> The index in SPEC_KEYS of key `name` (0: no such key).
    pure integer function spec_key_index(name) result(k)
        character(len=*), intent(in) :: name
        do k = 1, size(SPEC_KEYS)
            if (trim(SPEC_KEYS(k)%name) == trim(name)) return
        end do
        k = 0
    end function spec_key_index

    !> Whether the family can produce observation kind `kind` (the families
    !! column of the observation table).
    pure logical function observes(self, kind)
        class(experiment_family_t), intent(in) :: self
        integer, intent(in) :: kind
        observes = .false.
        if (kind < 1 .or. kind > size(KINDS)) return
        observes = iand(KINDS(kind)%families, self%family_code()) /= 0
    end function observes

    !> Whether the family's specs take key k of SPEC_KEYS.
    pure logical function accepts(self, k)
        class(experiment_family_t), intent(in) :: self
        integer, intent(in) :: k
        accepts = .false.
        if (k < 1 .or. k > size(SPEC_KEYS)) return
        accepts = SPEC_KEYS(k)%families == ALL_FAMILIES .or. &
                  iand(SPEC_KEYS(k)%families, self%family_code()) /= 0
    end function accepts
    !> The value of key `key` (EV_*; 0 for a number that is no key).
    elemental real(dp) function spec_get(self, key) result(x)
        class(experiment_spec_t), intent(in) :: self
        integer, intent(in) :: key
        x = 0.0_dp
        if (key >= 1 .and. key <= NEXPVAL) x = self%v(key)
    end function spec_get

    !> The value of key `key` as a whole number (a code, a count, a flag).
    elemental integer function spec_get_int(self, key) result(i)
        class(experiment_spec_t), intent(in) :: self
        integer, intent(in) :: key
        i = nint(self%get(key))
    end function spec_get_int

    !> Set key `key` (EV_*) to `x` (a number that is no key: nothing set).
    elemental subroutine spec_set(self, key, x)
        class(experiment_spec_t), intent(inout) :: self
        integer, intent(in) :: key
        real(dp), intent(in) :: x
        if (key >= 1 .and. key <= NEXPVAL) self%v(key) = x
    end subroutine spec_set

    !> The value of the key named `name` (SPEC_KEYS' names; 0 for a name
    !! that is no key: spec_key_index tells).
    pure real(dp) function spec_value_of(self, name) result(x)
        class(experiment_spec_t), intent(in) :: self
        character(len=*), intent(in) :: name
        x = self%get(spec_key_index(name))
    end function spec_value_of

    !> Set the key named `name` to `x`; a name that is no key is an input
    !! error naming it and the keys.
    pure subroutine spec_set_named(self, name, x, stat)
        class(experiment_spec_t), intent(inout) :: self
        character(len=*), intent(in) :: name
        real(dp), intent(in) :: x
        type(status_t), intent(inout) :: stat
        integer :: k
        k = spec_key_index(name)
        if (k == 0) then
            call set_status(stat, ERR_INPUT, 'experiment spec', "key '"//trim(name)// &
                            "' is unknown; expected one of "//spec_keys_text())
            return
        end if
        call self%set(k, x)
    end subroutine spec_set_named

    !> Whether the spec asks anything of the measurement chain: a key every
    !! family accepts (ALL_FAMILIES: t0, bias, scale, loss, burn-in,
    !! estimated sigmas, v0) set to a value other than 0.
    elemental logical function spec_chain_asked(self) result(asked)
        class(experiment_spec_t), intent(in) :: self
        integer :: k
        asked = .false.
        do k = 1, NEXPVAL
            if (SPEC_KEYS(k)%families == ALL_FAMILIES .and. self%v(k) /= 0.0_dp) asked = .true.
        end do
    end function spec_chain_asked

    !> Clear the rows' treatment of the measurement chain (loss, burn-in,
    !! estimated sigmas: beamid_chain_fit) to none.
    elemental subroutine spec_clear_treatment(self)
        class(experiment_spec_t), intent(inout) :: self
        call self%set(EV_LOSS, 0.0_dp)
        call self%set(EV_BURNIN, 0.0_dp)
        call self%set(EV_SIGEST, 0.0_dp)
    end subroutine spec_clear_treatment

    !> Take the measurement chain's keys (those every family accepts,
    !! ALL_FAMILIES) from spec `other`, the others kept.
    elemental subroutine spec_take_chain(self, other)
        class(experiment_spec_t), intent(inout) :: self
        type(experiment_spec_t), intent(in) :: other
        integer :: k
        do k = 1, NEXPVAL
            if (SPEC_KEYS(k)%families == ALL_FAMILIES) self%v(k) = other%v(k)
        end do
    end subroutine spec_take_chain

    !> The names of SPEC_KEYS, comma separated.
    pure function spec_keys_text() result(text)
        character(len=:), allocatable :: text
        integer :: k
        text = ''
        do k = 1, size(SPEC_KEYS)
            if (k > 1) text = text//', '
            text = text//trim(SPEC_KEYS(k)%name)
        end do
    end function spec_keys_text
end module beamid_family
