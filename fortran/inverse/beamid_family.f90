!> An experiment family: the abstract type every family of the inverse
!! problem extends (issue 25, "experiment families, an open list").
!!
!! A family owns its experiments and the data rows they predict: it builds
!! itself from its experiments' specs and its rows (`build`), evaluates the
!! predictions and Jacobian of all its rows at once (`evaluate`, the
!! residual_model_t interface: one type-bound call per evaluation, never one
!! per row), proposes probe rows for a diagnosis (`probe`), tells which
!! observation kinds it can produce (`observes`, from the families column of
!! beamid_observations) and where its mesh lives in a spec (`mesh_key`).
!! The problem (beamid_problem) holds a list of families (family_slot_t);
!! which family takes an experiment kind is the registry's business
!! (beamid_families): a new family is one module extending this type plus
!! one line there (docs/development.md, "Adding an experiment family").
!!
!! The spec of an experiment crosses as a kind (EXP_*) and a value column
!! (rows EV_*) until the named specs replace it; the layout lives here, once.
module beamid_family
    use beamid_kinds, only: dp
    use beamid_status, only: status_t
    use beamid_arclength, only: LOAD_TIP, LOAD_WIRE
    use beamid_estimation, only: residual_model_t
    use beamid_observations, only: observation_t, KINDS, FAM_STATIC, FAM_RELEASE, FAM_MODAL
    implicit none
    private

    public :: experiment_family_t, family_slot_t, spec_key_t, spec_key_index

    !> Experiment kinds: the static loads of beamid_arclength, and a release.
    integer, parameter, public :: EXP_TIP = LOAD_TIP, EXP_WIRE = LOAD_WIRE, EXP_RELEASE = 3
    !> A modal test about the equilibrium under a tip load (issue 27,
    !! beamid_modal_experiments).
    integer, parameter, public :: EXP_MODAL = 4
    !> Rows of an experiment's value column.
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
    integer, parameter, public :: NEXPVAL = 19

    !> A named key of an experiment's spec: its name (the deck's), the row
    !! of the value column it fills, the families that accept it (FAM_* bits
    !! of beamid_observations' families column; ALL_FAMILIES: the measurement
    !! chain's keys, which every family accepts and the problem checks) and
    !! the value an experiment of such a family takes when the key is not
    !! given.
    type :: spec_key_t
        character(len=17) :: name = ''
        integer :: row = 0
        integer :: families = 0
        real(dp) :: default = 0.0_dp
        character(len=80) :: about = ''
    end type spec_key_t

    integer, parameter, public :: ALL_FAMILIES = -1
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

    !> One family of experiments and the data rows they predict.
    type, abstract, extends(residual_model_t) :: experiment_family_t
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
        procedure(name_if), deferred, nopass :: name
        procedure(claims_if), deferred, nopass :: claims
        procedure(kind_label_if), deferred, nopass :: kind_label
        procedure(timed_if), deferred, nopass :: timed
        procedure(family_code_if), deferred, nopass :: family_code
        procedure(build_if), deferred :: build
        procedure, nopass :: mesh_key => no_mesh
        procedure :: probe => no_probe
        procedure :: probe_model => no_probe_model
        procedure :: observes
        procedure :: accepts
    end type experiment_family_t

    !> A slot of the problem's list of families.
    type :: family_slot_t
        class(experiment_family_t), allocatable :: item
    end type family_slot_t

    abstract interface
        !> The family's name in messages ('static', 'release').
        pure function name_if() result(text)
            character(len=:), allocatable :: text
        end function name_if
        !> Whether experiments of this kind (EXP_*) belong to the family.
        pure logical function claims_if(kind)
            integer, intent(in) :: kind
        end function claims_if
        !> The words for an experiment kind of the family ('tip load').
        pure function kind_label_if(kind) result(text)
            integer, intent(in) :: kind
            character(len=:), allocatable :: text
        end function kind_label_if
        !> Whether the family's rows are records in time (a row has t; a
        !! clock offset and a burn-in make sense).
        pure logical function timed_if()
        end function timed_if
        !> The family's code in the families column of beamid_observations.
        pure integer function family_code_if()
        end function family_code_if
        !> Build from the experiments' kinds and value columns and the
        !! family's rows (row_exp local experiment numbers 1..size(kinds)).
        subroutine build_if(self, nbeams, kinds, values, row_exp, row_t, row_obs, tol, stat)
            import :: experiment_family_t, dp, observation_t, status_t
            class(experiment_family_t), intent(inout) :: self
            integer, intent(in) :: nbeams, kinds(:), row_exp(:)
            real(dp), intent(in) :: values(:, :), row_t(:), tol
            type(observation_t), intent(in) :: row_obs(:)
            type(status_t), intent(inout) :: stat
        end subroutine build_if
    end interface

contains

    !> The row of a value column holding the family's elements per beam, 0
    !! when it has no mesh to refine.
    pure integer function no_mesh()
        no_mesh = 0
    end function no_mesh

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
end module beamid_family
