!> Kinds and physical constants shared by every beamid module.
module beamid_kinds
    use, intrinsic :: iso_fortran_env, only: real64, int32
    use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_positive_inf, ieee_quiet_nan
    implicit none
    private

    !> Working precision of all beamid computations.
    integer, parameter, public :: dp = real64
    !> Default integer kind used for sizes and codes.
    integer, parameter, public :: ik = int32

    real(dp), parameter, public :: pi = 3.14159265358979323846264338327950288_dp
    !> Standard gravity used for the friction normal force N = m g (Section 4.1.4).
    real(dp), parameter, public :: g_standard = 9.81_dp

    public :: infinity, not_a_number

contains

    pure real(dp) function infinity()
        infinity = ieee_value(1.0_dp, ieee_positive_inf)
    end function infinity

    pure real(dp) function not_a_number()
        not_a_number = ieee_value(1.0_dp, ieee_quiet_nan)
    end function not_a_number
end module beamid_kinds
