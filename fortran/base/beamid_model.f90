!> The beam chain: n >= 1 beams clamped at the root, point masses at the
!! joints and the tip, and the named effect parameters.
!!
!! Every model quantity is addressed by name. The flat parameter vector that
!! crosses the Python boundary has this fixed layout (nb = number of beams):
!!
!!  1. per beam i = 1..nb:            L<i> EI<i> EA<i> rho<i> C<i>
!!  2. per mass point k = 1..nb:      m J mu c   (k < nb: joint k, k = nb: tip)
!!       names: joint 1 is the elbow (m_elbow J_elbow mu_elbow c_elbow),
!!       joints k >= 2 are m_joint<k> ..., the tip is m_tip J_tip mu_tip c_tip
!!  3. per joint k = 1..nb-1:         rotational compliance (elbow_flex, joint<k>_flex)
!!  4. globals: axial_coupling root_flex eta r_motor tau_motor
!!  5. per beam i = 1..nb:            thick<i> (strip thickness, m: the gauge
!!       strain k t/2; appended after the globals so that every earlier
!!       index keeps its place)
!!
!! Null values switch an effect off: C = 0 (Eq. 16), flex = 0 (rigid), mu = c = 0,
!! eta = 0, tau_motor = 0. axial_coupling = 1 is the exact elastica, 0 the
!! dissertation's shear-only form of Eq. 9.
module beamid_model
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_INPUT, fmt_real, fmt_int
    implicit none
    private

    public :: chain_t, param_count, param_name, param_index_beam, param_index_mass
    public :: param_unit, param_group
    public :: param_index_joint_flex, param_index_global, param_index_thickness
    public :: chain_from_vector, param_problem
    public :: PER_BEAM, PER_MASS, NUM_GLOBAL, PACE_THICKNESS
    public :: IB_L, IB_EI, IB_EA, IB_RHO, IB_C, IM_M, IM_J, IM_MU, IM_C
    public :: IG_AXIAL_COUPLING, IG_ROOT_FLEX, IG_ETA, IG_R_MOTOR, IG_TAU_MOTOR

    integer, parameter :: PER_BEAM = 5, PER_MASS = 4, NUM_GLOBAL = 5
    integer, parameter :: IB_L = 1, IB_EI = 2, IB_EA = 3, IB_RHO = 4, IB_C = 5
    integer, parameter :: IM_M = 1, IM_J = 2, IM_MU = 3, IM_C = 4
    integer, parameter :: IG_AXIAL_COUPLING = 1, IG_ROOT_FLEX = 2, IG_ETA = 3, &
                          IG_R_MOTOR = 4, IG_TAU_MOTOR = 5

    !> Strip thickness t of the PACE beams (Section 4.1.4; EA = 12 EI / t^2):
    !! the default of every beam's thick<i>.
    real(dp), parameter :: PACE_THICKNESS = 0.00315976_dp

    character(len=*), parameter :: beam_names(PER_BEAM) = &
        [character(len=3) :: 'L', 'EI', 'EA', 'rho', 'C']
    character(len=*), parameter :: mass_names(PER_MASS) = &
        [character(len=2) :: 'm', 'J', 'mu', 'c']
    character(len=*), parameter :: global_names(NUM_GLOBAL) = &
        [character(len=14) :: 'axial_coupling', 'root_flex', 'eta', 'r_motor', 'tau_motor']
    !> Units of the parameters, in the order of the names above ('-': none;
    !! M = EI k + C k^3, Kelvin-Voigt eta, T = -r g Psidot; docs/static.md,
    !! docs/dynamics.md). A joint's flexibility (and the root's) is rad/(N m),
    !! a strip thickness m.
    character(len=*), parameter :: beam_units(PER_BEAM) = &
        [character(len=7) :: 'm', 'N m^2', 'N', 'kg/m', 'N m^4']
    character(len=*), parameter :: mass_units(PER_MASS) = &
        [character(len=6) :: 'kg', 'kg m^2', '-', 'N s/m']
    character(len=*), parameter :: global_units(NUM_GLOBAL) = &
        [character(len=9) :: '-', 'rad/(N m)', 's', 'N m s', 's']
    character(len=*), parameter :: FLEX_UNIT = 'rad/(N m)', THICKNESS_UNIT = 'm'

    !> A validated beam chain. Arrays are indexed by beam (1..nbeams) or by
    !! mass point (1..nbeams; the last one is the tip).
    type :: chain_t
        integer :: nbeams = 0
        real(dp), allocatable :: length(:), ei(:), ea(:), rho(:), cubic(:)
        real(dp), allocatable :: mass(:), inertia(:), friction(:), drag(:)
        real(dp), allocatable :: joint_flex(:)
        !> strip thickness per beam (m): only the gauge strain k t/2 uses it
        real(dp), allocatable :: thickness(:)
        real(dp) :: axial_coupling = 1.0_dp
        real(dp) :: root_flex = 0.0_dp
        real(dp) :: eta = 0.0_dp
        real(dp) :: r_motor = 1.0_dp
        real(dp) :: tau_motor = 0.0_dp
    end type chain_t

contains

    !> Number of named parameters of a chain of `nbeams` beams.
    pure integer function param_count(nbeams)
        integer, intent(in) :: nbeams
        param_count = PER_BEAM*nbeams + PER_MASS*nbeams + (nbeams - 1) + NUM_GLOBAL + nbeams
    end function param_count

    pure integer function param_index_beam(nbeams, beam, which)
        integer, intent(in) :: nbeams, beam, which
        param_index_beam = PER_BEAM*(beam - 1) + which + 0*nbeams
    end function param_index_beam

    pure integer function param_index_mass(nbeams, point, which)
        integer, intent(in) :: nbeams, point, which
        param_index_mass = PER_BEAM*nbeams + PER_MASS*(point - 1) + which
    end function param_index_mass

    pure integer function param_index_joint_flex(nbeams, joint)
        integer, intent(in) :: nbeams, joint
        param_index_joint_flex = (PER_BEAM + PER_MASS)*nbeams + joint
    end function param_index_joint_flex

    pure integer function param_index_global(nbeams, which)
        integer, intent(in) :: nbeams, which
        param_index_global = (PER_BEAM + PER_MASS)*nbeams + (nbeams - 1) + which
    end function param_index_global

    !> Index of beam `beam`'s strip thickness thick<beam> (after the globals).
    pure integer function param_index_thickness(nbeams, beam)
        integer, intent(in) :: nbeams, beam
        param_index_thickness = (PER_BEAM + PER_MASS)*nbeams + (nbeams - 1) + NUM_GLOBAL + beam
    end function param_index_thickness

    !> Name of parameter `index` (1-based) of a chain of `nbeams` beams.
    pure function param_name(nbeams, index) result(name)
        integer, intent(in) :: nbeams, index
        character(len=:), allocatable :: name
        integer :: i, k
        i = index
        if (i < 1 .or. i > param_count(nbeams)) then
            name = ''
        else if (i <= PER_BEAM*nbeams) then
            k = (i - 1)/PER_BEAM + 1
            name = trim(beam_names(i - PER_BEAM*(k - 1)))//fmt_int(k)
        else if (i <= (PER_BEAM + PER_MASS)*nbeams) then
            i = i - PER_BEAM*nbeams
            k = (i - 1)/PER_MASS + 1
            name = trim(mass_names(i - PER_MASS*(k - 1)))//'_'//point_name(nbeams, k)
        else if (i <= (PER_BEAM + PER_MASS)*nbeams + nbeams - 1) then
            k = i - (PER_BEAM + PER_MASS)*nbeams
            name = point_name(nbeams, k)//'_flex'
        else if (i <= (PER_BEAM + PER_MASS)*nbeams + nbeams - 1 + NUM_GLOBAL) then
            k = i - (PER_BEAM + PER_MASS)*nbeams - (nbeams - 1)
            name = trim(global_names(k))
        else
            k = i - param_index_thickness(nbeams, 0)
            name = 'thick'//fmt_int(k)
        end if
    end function param_name

    !> Unit of parameter `index` (1-based) of a chain of `nbeams` beams ('-':
    !! none; '' outside the vector).
    pure function param_unit(nbeams, index) result(unit)
        integer, intent(in) :: nbeams, index
        character(len=:), allocatable :: unit
        integer :: i
        i = index
        select case (param_group(nbeams, index))
        case ('beam')
            if (i <= PER_BEAM*nbeams) then
                unit = trim(beam_units(modulo(i - 1, PER_BEAM) + 1))
            else
                unit = THICKNESS_UNIT
            end if
        case ('point')
            i = i - PER_BEAM*nbeams
            unit = trim(mass_units(modulo(i - 1, PER_MASS) + 1))
        case ('joint')
            unit = FLEX_UNIT
        case ('global')
            unit = trim(global_units(i - param_index_global(nbeams, 0)))
        case default
            unit = ''
        end select
    end function param_unit

    !> What parameter `index` (1-based) of a chain of `nbeams` beams belongs
    !! to: 'beam' (one per beam: L, EI, EA, rho, C, thick), 'point' (one per
    !! mass point: m, J, mu, c), 'joint' (one per joint: its flexibility),
    !! 'global' (one per chain); '' outside the vector.
    pure function param_group(nbeams, index) result(group)
        integer, intent(in) :: nbeams, index
        character(len=:), allocatable :: group
        if (index < 1 .or. index > param_count(nbeams)) then
            group = ''
        else if (index <= PER_BEAM*nbeams) then
            group = 'beam'
        else if (index <= (PER_BEAM + PER_MASS)*nbeams) then
            group = 'point'
        else if (index <= param_index_global(nbeams, 0)) then
            group = 'joint'
        else if (index <= param_index_thickness(nbeams, 0)) then
            group = 'global'
        else
            group = 'beam'
        end if
    end function param_group

    pure function point_name(nbeams, point) result(name)
        integer, intent(in) :: nbeams, point
        character(len=:), allocatable :: name
        if (point == nbeams) then
            name = 'tip'
        else if (point == 1) then
            name = 'elbow'
        else
            name = 'joint'//fmt_int(point)
        end if
    end function point_name

    !> Build and validate a chain from the flat parameter vector. Every
    !! problem is reported (the first in the message, with a count of the rest).
    pure subroutine chain_from_vector(nbeams, params, chain, stat)
        integer, intent(in) :: nbeams
        real(dp), intent(in) :: params(:)
        type(chain_t), intent(out) :: chain
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'model'
        integer :: i, nbad
        character(len=:), allocatable :: first, problem

        if (nbeams < 1) then
            call set_status(stat, ERR_INPUT, where, 'number of beams = '//fmt_int(nbeams)// &
                            ', expected at least 1')
            return
        end if
        if (size(params) /= param_count(nbeams)) then
            call set_status(stat, ERR_INPUT, where, 'parameter vector has '// &
                            fmt_int(size(params))//' values, expected '// &
                            fmt_int(param_count(nbeams))//' for '//fmt_int(nbeams)//' beams')
            return
        end if
        nbad = 0
        first = ''
        do i = 1, size(params)
            problem = param_problem(nbeams, i, params(i))
            if (len(problem) > 0) then
                nbad = nbad + 1
                if (nbad == 1) first = problem
            end if
        end do
        if (nbad > 0) then
            if (nbad > 1) first = first//' (and '//fmt_int(nbad - 1)//' more bad parameters)'
            call set_status(stat, ERR_INPUT, where, first)
            return
        end if

        chain%nbeams = nbeams
        chain%length = params([(param_index_beam(nbeams, i, IB_L), i = 1, nbeams)])
        chain%ei = params([(param_index_beam(nbeams, i, IB_EI), i = 1, nbeams)])
        chain%ea = params([(param_index_beam(nbeams, i, IB_EA), i = 1, nbeams)])
        chain%rho = params([(param_index_beam(nbeams, i, IB_RHO), i = 1, nbeams)])
        chain%cubic = params([(param_index_beam(nbeams, i, IB_C), i = 1, nbeams)])
        chain%mass = params([(param_index_mass(nbeams, i, IM_M), i = 1, nbeams)])
        chain%inertia = params([(param_index_mass(nbeams, i, IM_J), i = 1, nbeams)])
        chain%friction = params([(param_index_mass(nbeams, i, IM_MU), i = 1, nbeams)])
        chain%drag = params([(param_index_mass(nbeams, i, IM_C), i = 1, nbeams)])
        chain%joint_flex = params([(param_index_joint_flex(nbeams, i), i = 1, nbeams - 1)])
        chain%axial_coupling = params(param_index_global(nbeams, IG_AXIAL_COUPLING))
        chain%root_flex = params(param_index_global(nbeams, IG_ROOT_FLEX))
        chain%eta = params(param_index_global(nbeams, IG_ETA))
        chain%r_motor = params(param_index_global(nbeams, IG_R_MOTOR))
        chain%tau_motor = params(param_index_global(nbeams, IG_TAU_MOTOR))
        chain%thickness = params([(param_index_thickness(nbeams, i), i = 1, nbeams)])
    end subroutine chain_from_vector

    !> Empty when `value` is legal for parameter `index`; otherwise a message
    !! naming the parameter, the value and what was expected.
    pure function param_problem(nbeams, index, value) result(problem)
        integer, intent(in) :: nbeams, index
        real(dp), intent(in) :: value
        character(len=:), allocatable :: problem
        character(len=:), allocatable :: expected
        logical :: positive, bad
        ! (the name is formatted only for a bad value: every solve validates
        ! its whole parameter vector)
        ! strictly positive: lengths, stiffnesses, density, thickness; the
        ! rest >= 0, except C (either sign, Eq. 16) and axial_coupling (0..1).
        positive = (index <= PER_BEAM*nbeams .and. mod(index - 1, PER_BEAM) + 1 /= IB_C) &
                   .or. index > param_index_thickness(nbeams, 0)
        if (.not. ieee_is_finite(value)) then
            bad = .true.
            expected = 'a finite number'
        else if (positive) then
            bad = value <= 0.0_dp
            expected = 'a positive number'
        else if (index == param_index_global(nbeams, IG_AXIAL_COUPLING)) then
            bad = value < 0.0_dp .or. value > 1.0_dp
            expected = 'a value in [0, 1] (0 shear-only Eq. 9, 1 exact elastica)'
        else if (index <= PER_BEAM*nbeams) then
            bad = .false.
            expected = ''
        else
            bad = value < 0.0_dp
            expected = 'a non-negative number'
        end if
        if (bad) then
            problem = param_name(nbeams, index)//' = '//fmt_real(value)//', expected '//expected
        else
            problem = ''
        end if
    end function param_problem
end module beamid_model
