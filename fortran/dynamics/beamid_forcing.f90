!> Forcings of the dynamic system: loads that may change in time (issue 25,
!! "loads in time"). A forcing adds a generalized force F_l(t, q, v) to the
!! right side of M(q) q'' = F (beamid_dynamics), and gives
!!
!! - its work rate F_l . v, integrated as one work line of the energy
!!   ledger (named by work_name, exported like the parameter names);
!! - its Jacobians: kb -= dF_l/dq and cb -= dF_l/dv (band storage of the
!!   free unknowns, the sign convention of dyn_jacobian: K = -dF/dq);
!! - its parameter derivatives dF_l/dp_i for its own parameters (a
!!   history's amplitude, duration or scale), which forward sensitivities
!!   take as dyn_param_t entries of kind DP_FORCING;
!! - its breakpoints: times where F_l is not smooth, that the integrators
!!   step onto (a table's rows, the end of a half-sine).
!!
!! The dynamic system holds any number of them (dyn_system_t%loads); time
!! enters the model only through dyn_eval (beamid_dynamics), which the
!! integrators call. With no forcing, every evaluation is the autonomous
!! model of Chapter IV-V, bit for bit.
module beamid_forcing
    use beamid_kinds, only: dp
    implicit none
    private

    public :: forcing_t, forcing_slot_t

    !> A generalized force that may depend on time, state and its own
    !! parameters. Extend it and implement the deferred procedures.
    type, abstract :: forcing_t
    contains
        !> f += F_l(t, q, v); power = F_l . v (its work rate)
        procedure(forcing_apply), deferred :: apply
        !> kb -= dF_l/dq; cb -= dF_l/dv (cb may be absent when not velocity_coupled)
        procedure(forcing_jacobian), deferred :: jacobian
        !> name of its work line of the ledger
        procedure(forcing_name), deferred :: work_name
        !> does F_l depend on v (then the Jacobian C is not zero)?
        procedure :: velocity_coupled => forcing_not_coupled
        !> number of its own parameters, their names, dF_l/dp_i
        procedure :: nparams => forcing_no_params
        procedure :: param_name => forcing_param_name
        procedure :: dforce => forcing_no_dforce
        !> fp += dF_l/dp for a mass parameter of the chain: the density of
        !! beam `beam` (> 0), or the point mass whose u is free unknown
        !! `iu_point` (> 0); forces proportional to the mass (a hub frame's
        !! inertial forces) depend on them
        procedure :: dmass => forcing_no_dmass
        !> times in (t0, t1] where F_l is not smooth, ascending
        procedure :: breakpoints => forcing_no_breaks
        !> d tb / dp_i of breakpoint tb where F_l jumps (0: p_i does not move
        !! it): the state sensitivities then jump by (f- - f+) d tb/dp_i
        procedure :: dbreak => forcing_no_dbreak
    end type forcing_t

    !> One entry of a list of forcings (a polymorphic component).
    type :: forcing_slot_t
        class(forcing_t), allocatable :: f
    end type forcing_slot_t

    abstract interface
        pure subroutine forcing_apply(self, t, q, v, f, power)
            import :: forcing_t, dp
            class(forcing_t), intent(in) :: self
            real(dp), intent(in) :: t, q(:), v(:)
            real(dp), intent(inout) :: f(:)
            real(dp), intent(out) :: power
        end subroutine forcing_apply

        pure subroutine forcing_jacobian(self, t, q, v, kl, ku, kb, cb)
            import :: forcing_t, dp
            class(forcing_t), intent(in) :: self
            real(dp), intent(in) :: t, q(:), v(:)
            integer, intent(in) :: kl, ku
            real(dp), intent(inout) :: kb(:, :)
            real(dp), intent(inout), optional :: cb(:, :)
        end subroutine forcing_jacobian

        pure function forcing_name(self) result(name)
            import :: forcing_t
            class(forcing_t), intent(in) :: self
            character(len=:), allocatable :: name
        end function forcing_name
    end interface

contains

    pure logical function forcing_not_coupled(self) result(coupled)
        class(forcing_t), intent(in) :: self
        coupled = .false.
    end function forcing_not_coupled

    pure integer function forcing_no_params(self) result(np)
        class(forcing_t), intent(in) :: self
        np = 0
    end function forcing_no_params

    pure function forcing_param_name(self, i) result(name)
        class(forcing_t), intent(in) :: self
        integer, intent(in) :: i
        character(len=:), allocatable :: name
        character(len=12) :: buf
        write (buf, '(i0)') i
        name = self%work_name()//'_p'//trim(buf)
    end function forcing_param_name

    !> fp += dF_l/dp_i (nothing without parameters)
    pure subroutine forcing_no_dforce(self, i, t, q, v, fp)
        class(forcing_t), intent(in) :: self
        integer, intent(in) :: i
        real(dp), intent(in) :: t, q(:), v(:)
        real(dp), intent(inout) :: fp(:)
    end subroutine forcing_no_dforce

    pure subroutine forcing_no_dmass(self, beam, iu_point, t, q, v, fp)
        class(forcing_t), intent(in) :: self
        integer, intent(in) :: beam, iu_point
        real(dp), intent(in) :: t, q(:), v(:)
        real(dp), intent(inout) :: fp(:)
    end subroutine forcing_no_dmass

    pure real(dp) function forcing_no_dbreak(self, i, tb) result(d)
        class(forcing_t), intent(in) :: self
        integer, intent(in) :: i
        real(dp), intent(in) :: tb
        d = 0.0_dp
    end function forcing_no_dbreak

    pure function forcing_no_breaks(self, t0, t1) result(tb)
        class(forcing_t), intent(in) :: self
        real(dp), intent(in) :: t0, t1
        real(dp), allocatable :: tb(:)
        allocate (tb(0))
    end function forcing_no_breaks

end module beamid_forcing
