!> The candidate effects, one table (issue 25).
!!
!! An effect is a piece of physics a model can switch on: its parameters
!! (by pattern: one global parameter, one per beam, one per mass point, or a
!! joint's compliance), the value that switches it off (null value), the
!! physical bounds of those parameters, and the experiment families that can
!! see it, each with the effect's place among that family's default
!! candidates. Sidedness follows from the table: an effect whose null value
!! is its lower bound is one-sided (its score test and Wald tests only look
!! at the physical side, beamid_estimation).
!!
!! Read by the deck reader (candidate names, their default list, the
!! message naming the known ones), the estimation problems (bounds and null
!! values of every parameter: beamid_inverse), the deck runners' diagnose and
!! improve (beamid_tasks) and, through the binding (api_effect_table), the
!! Python `Effect` list. Python's `register_effect` adds user blocks beside
!! these.
module beamid_effects
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_INPUT
    use beamid_model, only: param_count, param_index_beam, param_index_mass, &
                            param_index_joint_flex, param_index_global, IB_C, IM_MU, IM_C, &
                            IM_J, IG_AXIAL_COUPLING, IG_ROOT_FLEX, IG_ETA, IG_TAU_MOTOR
    implicit none
    private

    public :: effect_t, EFFECTS, NEFFECTS, NFAMILY, effect_index, effect_params, &
              effect_one_sided, known_effects, default_effects, effect_bounds, &
              effect_null_values

    !> Patterns of an effect's parameters (effect_t%pattern; `which` says which).
    integer, parameter, public :: EP_NONE = 0     !< none (mesh: a test of the discretization)
    integer, parameter, public :: EP_GLOBAL = 1   !< one global parameter, which = IG_*
    integer, parameter, public :: EP_PER_BEAM = 2 !< one per beam, which = IB_*
    !> one per mass point (elbow, joints, tip), which = IM_*
    integer, parameter, public :: EP_PER_MASS = 3
    !> the compliance of joint `which` (1: the elbow), when the chain has that joint
    integer, parameter, public :: EP_JOINT = 4

    !> Experiment families (effect_t%rank), and their names in the binding.
    integer, parameter, public :: FAMILY_STATIC = 1, FAMILY_RELEASE = 2
    integer, parameter :: NFAMILY = 2
    character(len=*), parameter, public :: FAMILY_NAMES(NFAMILY) = [character(len=7) :: &
        'static', 'dynamic']

    !> Length of an effect's name.
    integer, parameter, public :: NAME_LEN = 16

    !> One effect.
    type :: effect_t
        character(len=NAME_LEN) :: name = ''
        integer :: pattern = EP_NONE
        integer :: which = 0
        real(dp) :: null_value = 0.0_dp   !< switched off
        real(dp) :: lower = 0.0_dp        !< physical bounds of its parameters
        real(dp) :: upper = huge(1.0_dp)
        !> place among each family's default candidates (FAMILY_*); 0: that
        !! family cannot see the effect
        integer :: rank(NFAMILY) = 0
        character(len=128) :: description = ''
    end type effect_t

    integer, parameter :: NEFFECTS = 10
    !> The table, in the order messages name the effects.
    type(effect_t), parameter :: EFFECTS(NEFFECTS) = [ &
        effect_t('axial_coupling', EP_GLOBAL, IG_AXIAL_COUPLING, upper=1.0_dp, rank=[1, 0], &
                 description="exact elastica: the axial force times curvature term that the "// &
                 "seed's shear-only Eq. 9 omits (axial_coupling from 0 towards 1)"), &
        effect_t('material_cubic', EP_PER_BEAM, IB_C, lower=-huge(1.0_dp), rank=[2, 0], &
                 description='cubic moment-curvature law M = EI k + C k^3 (Eq. 16)'), &
        effect_t('elbow_flex', EP_JOINT, 1, rank=[3, 6], &
                 description='rotational compliance of the elbow joint (rad per N m)'), &
        effect_t('root_flex', EP_GLOBAL, IG_ROOT_FLEX, rank=[4, 7], &
                 description='rotational compliance of the shoulder clamp (rad per N m)'), &
        effect_t('friction', EP_PER_MASS, IM_MU, rank=[0, 1], &
                 description='Coulomb friction at the masses (Eq. 101-102)'), &
        effect_t('drag', EP_PER_MASS, IM_C, rank=[0, 2], &
                 description='viscous air drag -c v at the masses'), &
        effect_t('rotary_inertia', EP_PER_MASS, IM_J, rank=[0, 3], &
                 description='rotary inertia of the end masses (Eq. 130-132)'), &
        effect_t('kelvin_voigt', EP_GLOBAL, IG_ETA, rank=[0, 4], &
                 description='Kelvin-Voigt structural damping eta EI dchi/dt'), &
        effect_t('motor_lag', EP_GLOBAL, IG_TAU_MOTOR, rank=[0, 5], &
                 description="first-order lag of the tip motor's torque"), &
        effect_t('mesh', EP_NONE, 0, rank=[0, 8], &
                 description='the discretization: the same fit at twice the elements per beam')]

contains

    !> Position of effect `name` in the table (0 when unknown).
    pure integer function effect_index(name)
        character(len=*), intent(in) :: name
        integer :: i
        effect_index = 0
        do i = 1, NEFFECTS
            if (trim(adjustl(name)) == trim(EFFECTS(i)%name)) effect_index = i
        end do
    end function effect_index

    !> Every effect name, comma separated (for messages).
    pure function known_effects() result(text)
        character(len=:), allocatable :: text
        integer :: i
        text = trim(EFFECTS(1)%name)
        do i = 2, NEFFECTS
            text = text//', '//trim(EFFECTS(i)%name)
        end do
    end function known_effects

    !> The default candidates of a family (FAMILY_*), in their order.
    pure function default_effects(family) result(names)
        integer, intent(in) :: family
        character(len=NAME_LEN), allocatable :: names(:)
        integer :: i, n
        n = 0
        do i = 1, NEFFECTS
            if (EFFECTS(i)%rank(family) > 0) n = n + 1
        end do
        allocate (names(n))
        do i = 1, NEFFECTS
            if (EFFECTS(i)%rank(family) > 0) names(EFFECTS(i)%rank(family)) = EFFECTS(i)%name
        end do
    end function default_effects

    !> One-sided: the null value is the lower bound (the physical values lie
    !! on one side of it).
    elemental logical function effect_one_sided(e)
        type(effect_t), intent(in) :: e
        effect_one_sided = e%null_value <= e%lower
    end function effect_one_sided

    !> Parameter indices of effect `name` in a chain of `nbeams` beams (a
    !! joint the chain lacks, or `mesh`: none); an unknown name is ERR_INPUT
    !! (params empty).
    pure subroutine effect_params(nbeams, name, params, stat)
        integer, intent(in) :: nbeams
        character(len=*), intent(in) :: name
        integer, allocatable, intent(out) :: params(:)
        type(status_t), intent(inout) :: stat
        integer :: k
        k = effect_index(name)
        if (k == 0) then
            allocate (params(0))
            call set_status(stat, ERR_INPUT, 'effects', 'unknown effect "'//trim(name)// &
                            '", expected one of '//known_effects())
            return
        end if
        params = pattern_params(nbeams, EFFECTS(k))
    end subroutine effect_params

    pure function pattern_params(nbeams, e) result(params)
        integer, intent(in) :: nbeams
        type(effect_t), intent(in) :: e
        integer, allocatable :: params(:)
        integer :: i
        select case (e%pattern)
        case (EP_GLOBAL)
            params = [param_index_global(nbeams, e%which)]
        case (EP_PER_BEAM)
            params = [(param_index_beam(nbeams, i, e%which), i=1, nbeams)]
        case (EP_PER_MASS)
            params = [(param_index_mass(nbeams, i, e%which), i=1, nbeams)]
        case (EP_JOINT)
            if (nbeams > e%which) then
                params = [param_index_joint_flex(nbeams, e%which)]
            else
                allocate (params(0))
            end if
        case default
            allocate (params(0))
        end select
    end function pattern_params

    !> Physical bounds of every parameter of a chain of `nbeams` beams: those
    !! of the effect a parameter belongs to; lengths, stiffnesses, densities,
    !! masses and the motor's r above 0 (lower bound 0, never reached: the
    !! solvers reject it).
    pure subroutine effect_bounds(nbeams, lower, upper)
        integer, intent(in) :: nbeams
        real(dp), allocatable, intent(out) :: lower(:), upper(:)
        integer :: i
        integer, allocatable :: p(:)
        allocate (lower(param_count(nbeams)), source=0.0_dp)
        allocate (upper(param_count(nbeams)), source=huge(1.0_dp))
        do i = 1, NEFFECTS
            p = pattern_params(nbeams, EFFECTS(i))
            lower(p) = EFFECTS(i)%lower
            upper(p) = EFFECTS(i)%upper
        end do
    end subroutine effect_bounds

    !> Null (switched-off) values of every parameter: the effects' (C = 0,
    !! compliances 0, axial_coupling = 0: the seed's shear-only form of Eq.
    !! 9); 0 as a NaN-free placeholder for the others.
    pure subroutine effect_null_values(nbeams, null_values)
        integer, intent(in) :: nbeams
        real(dp), allocatable, intent(out) :: null_values(:)
        integer :: i
        allocate (null_values(param_count(nbeams)), source=0.0_dp)
        do i = 1, NEFFECTS
            null_values(pattern_params(nbeams, EFFECTS(i))) = EFFECTS(i)%null_value
        end do
    end subroutine effect_null_values
end module beamid_effects
