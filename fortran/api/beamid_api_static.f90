!> f2py binding of the model and the arc-length static solver: argument
!! conversion and one library call each.
!!
!! Plain arrays, c_int/c_double kinds and an integer status with a
!! 256-character message: nothing else crosses into Python. Status codes
!! follow beamid_status (0 ok, < 0 input error, > 0 numerical failure);
!! array sizes that follow from the arguments are hidden from Python.
!! Outputs of a failed call are zeros: f2py allocates output arrays zeroed and
!! declares output scalars = 0 (characters blank), so no entry zeroes them.
module beamid_api_static
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK, ERR_INPUT, set_status, status_out, fmt_int
    use beamid_model, only: chain_t, chain_from_vector, param_count, param_name, param_unit, &
                            param_group
    use beamid_presets, only: preset_params
    use beamid_arclength, only: static_solution_t, solve_static, static_shape, &
                                static_load_from_values, static_options_from_tol
    implicit none
    private

    public :: api_param_names, api_param_count, api_param_name, api_check_params
    public :: api_param_info
    public :: api_static_solve, api_static_shape, api_preset_size, api_preset

contains

    !> Parameter names of a chain of nbeams beams, space separated, in the
    !! order of the parameter vector.
    subroutine api_param_names(nbeams, names, code, message)
        integer(c_int), intent(in) :: nbeams
        character(len=8192), intent(out) :: names
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        character(len=:), allocatable :: joined
        type(status_t) :: stat
        integer :: i
        joined = ''
        names = ''
        ! the names' own length bounds the chain, not a guess per name (the
        ! thicknesses appended after the globals made 24 a name cost 3 beams)
        if (nbeams >= 1) then
            do i = 1, param_count(int(nbeams))
                joined = joined//param_name(int(nbeams), i)//' '
            end do
        end if
        if (nbeams < 1 .or. len(joined) > len(names)) then
            call set_status(stat, ERR_INPUT, 'api_param_names', 'cannot name the parameters of '// &
                            fmt_int(int(nbeams))//' beams')
        else
            names = joined
        end if
        call status_out(stat, code, message)
    end subroutine api_param_names

    !> Length of the parameter vector of a chain of nbeams beams (with
    !! api_param_name: the names one by one, so no text buffer bounds the
    !! chain).
    subroutine api_param_count(nbeams, count, code, message)
        integer(c_int), intent(in) :: nbeams
        integer(c_int), intent(out) :: count, code
        character(len=256), intent(out) :: message
        type(status_t) :: stat
        count = 0
        if (nbeams < 1) then
            call set_status(stat, ERR_INPUT, 'api_param_count', 'nbeams = '// &
                            fmt_int(int(nbeams))//', expected at least 1')
        else
            count = int(param_count(int(nbeams)), c_int)
        end if
        call status_out(stat, code, message)
    end subroutine api_param_count

    !> Name of parameter i (1-based) of a chain of nbeams beams.
    subroutine api_param_name(nbeams, i, name, code, message)
        integer(c_int), intent(in) :: nbeams, i
        character(len=64), intent(out) :: name
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(status_t) :: stat
        name = ''
        if (nbeams < 1) then
            call set_status(stat, ERR_INPUT, 'api_param_name', 'nbeams = '// &
                            fmt_int(int(nbeams))//', expected at least 1')
        else if (i < 1 .or. i > param_count(int(nbeams))) then
            call set_status(stat, ERR_INPUT, 'api_param_name', 'parameter '//fmt_int(int(i))// &
                            ', expected 1..'//fmt_int(param_count(int(nbeams))))
        else
            name = param_name(int(nbeams), int(i))
        end if
        call status_out(stat, code, message)
    end subroutine api_param_name

    !> Unit ('-': none) and group of parameter i (1-based) of a chain of
    !! nbeams beams (beamid_model param_unit, param_group: 'beam', 'point',
    !! 'joint' or 'global').
    subroutine api_param_info(nbeams, i, unit, group, code, message)
        integer(c_int), intent(in) :: nbeams, i
        character(len=16), intent(out) :: unit, group
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        character(len=64) :: name
        name = ''
        unit = ''
        group = ''
        call api_param_name(nbeams, i, name, code, message)
        if (code /= 0) return
        unit = param_unit(int(nbeams), int(i))
        group = param_group(int(nbeams), int(i))
    end subroutine api_param_info

    !> Number of beams of a preset ('pace', 'cantilever'); code < 0 if unknown.
    subroutine api_preset_size(name, nbeams, code, message)
        character(len=*), intent(in) :: name
        integer(c_int), intent(out) :: nbeams, code
        character(len=256), intent(out) :: message
        type(status_t) :: stat
        real(dp), allocatable :: params(:)
        call preset_params(trim(name), nbeams, params, stat)
        call status_out(stat, code, message)
    end subroutine api_preset_size

    !> Parameter vector of a preset (nparams from api_preset_size).
    subroutine api_preset(name, nparams, params, code, message)
        character(len=*), intent(in) :: name
        integer(c_int), intent(in) :: nparams
        real(c_double), intent(out) :: params(nparams)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(status_t) :: stat
        real(dp), allocatable :: values(:)
        integer :: nb
        call preset_params(trim(name), nb, values, stat)
        if (stat%code == STATUS_OK .and. size(values) /= nparams) then
            call set_status(stat, ERR_INPUT, 'api_preset', 'wrong parameter count')
        end if
        if (stat%code == STATUS_OK) params = values
        call status_out(stat, code, message)
    end subroutine api_preset

    !> Validate a parameter vector; message names the first bad parameter.
    subroutine api_check_params(nbeams, nparams, params, code, message)
        !f2py intent(hide) nparams
        integer(c_int), intent(in) :: nbeams, nparams
        real(c_double), intent(in) :: params(nparams)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(chain_t) :: chain
        type(status_t) :: stat
        call chain_from_vector(int(nbeams), params, chain, stat)
        call status_out(stat, code, message)
    end subroutine api_check_params

    !> Solve a static load case. load_kind 1: tip force (fx, fy) and moment;
    !! 2: radial wire of length load_values(4). wrt: 1-based parameter indices.
    !! info = (Newton iterations, load steps); unknowns = k(0), Q(0), N(0), T.
    subroutine api_static_solve(nbeams, nparams, params, load_kind, load_values, nwrt, wrt, &
                                tol, outputs, doutputs, unknowns, info, code, message)
        !f2py intent(hide) nparams, nwrt
        integer(c_int), intent(in) :: nbeams, nparams, load_kind, nwrt
        real(c_double), intent(in) :: params(nparams), load_values(4), tol
        integer(c_int), intent(in) :: wrt(nwrt)
        real(c_double), intent(out) :: outputs(8), doutputs(8, nwrt), unknowns(4)
        integer(c_int), intent(out) :: info(2)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(chain_t) :: chain
        type(status_t) :: stat
        type(static_solution_t) :: sol
        call chain_from_vector(int(nbeams), params, chain, stat)
        if (stat%code == STATUS_OK) then
            call solve_static(chain, static_load_from_values(load_kind, load_values), wrt, &
                              static_options_from_tol(tol), sol, stat)
        end if
        if (stat%code == STATUS_OK) then
            outputs = sol%outputs
            doutputs = sol%doutputs
            unknowns = sol%unknowns
            info = [sol%newton_iterations, sol%load_steps]
        end if
        call status_out(stat, code, message)
    end subroutine api_static_solve

    !> Shape at arc positions s (ascending) from converged unknowns.
    subroutine api_static_shape(nbeams, nparams, params, load_kind, load_values, unknowns, &
                                tol, npts, s, x, y, psi, moment, code, message)
        !f2py intent(hide) nparams, npts
        integer(c_int), intent(in) :: nbeams, nparams, load_kind, npts
        real(c_double), intent(in) :: params(nparams), load_values(4), unknowns(4), tol
        real(c_double), intent(in) :: s(npts)
        real(c_double), intent(out) :: x(npts), y(npts), psi(npts), moment(npts)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(chain_t) :: chain
        type(status_t) :: stat
        call chain_from_vector(int(nbeams), params, chain, stat)
        if (stat%code == STATUS_OK) then
            call static_shape(chain, static_load_from_values(load_kind, load_values), unknowns, &
                              static_options_from_tol(tol), s, x, y, psi, moment, stat)
        end if
        call status_out(stat, code, message)
    end subroutine api_static_shape
end module beamid_api_static
