!> Built-in models: the PACE two-beam arm (Table 1, Section 4.1.4) and a
!! single cantilever strip of the PACE cross-section.
module beamid_presets
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_INPUT
    use beamid_model, only: param_count, param_index_beam, param_index_mass, &
                            param_index_global, param_index_thickness, PACE_THICKNESS, &
                            IB_L, IB_EI, IB_EA, IB_RHO, IB_C, IM_M, IM_J, &
                            IG_R_MOTOR
    implicit none
    private

    public :: preset_params, PACE_THICKNESS

contains

    !> Parameter vector of a preset: 'pace' (2 beams) or 'cantilever' (1 beam,
    !! the PACE beam 1 section without end masses). Effects are off.
    pure subroutine preset_params(name, nbeams, params, stat)
        character(len=*), intent(in) :: name
        integer, intent(out) :: nbeams
        real(dp), allocatable, intent(out) :: params(:)
        type(status_t), intent(inout) :: stat
        select case (trim(name))
        case ('pace')
            nbeams = 2
            allocate (params(param_count(nbeams)), source=0.0_dp)
            call set_beam(params, 1, 0.776_dp, 11.413_dp, 0.532_dp)
            call set_beam(params, 2, 0.714_dp, 11.275_dp, 0.530_dp)
            ! elbow and tip masses with their rotary inertia (Table 1)
            params(param_index_mass(nbeams, 1, IM_M)) = 4.280_dp
            params(param_index_mass(nbeams, 1, IM_J)) = 122.982e-4_dp
            params(param_index_mass(nbeams, 2, IM_M)) = 1.038_dp
            params(param_index_mass(nbeams, 2, IM_J)) = 15.244e-4_dp
        case ('cantilever')
            nbeams = 1
            allocate (params(param_count(nbeams)), source=0.0_dp)
            call set_beam(params, 1, 0.776_dp, 11.413_dp, 0.532_dp)
        case default
            nbeams = 0
            allocate (params(0))
            call set_status(stat, ERR_INPUT, 'preset', 'unknown preset "'//trim(name)// &
                            '", expected "pace" or "cantilever"')
            return
        end select
        params(param_index_global(nbeams, IG_R_MOTOR)) = 1.0_dp
        ! axial_coupling defaults to 1: the exact elastica
        params(param_index_global(nbeams, 1)) = 1.0_dp

    contains

        pure subroutine set_beam(p, i, length, ei, rho)
            real(dp), intent(inout) :: p(:)
            integer, intent(in) :: i
            real(dp), intent(in) :: length, ei, rho
            p(param_index_beam(nbeams, i, IB_L)) = length
            p(param_index_beam(nbeams, i, IB_EI)) = ei
            p(param_index_beam(nbeams, i, IB_EA)) = 12.0_dp*ei/PACE_THICKNESS**2
            p(param_index_beam(nbeams, i, IB_RHO)) = rho
            p(param_index_beam(nbeams, i, IB_C)) = 0.0_dp
            p(param_index_thickness(nbeams, i)) = PACE_THICKNESS
        end subroutine set_beam
    end subroutine preset_params
end module beamid_presets
