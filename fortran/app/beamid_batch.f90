!> beamid-batch DECK: run a namelist deck without Python.
!!
!! Exit codes: 0 success, 2 bad deck or input, 3 numerical failure (no
!! convergence), 4 file error. One line on standard error says what failed.
!! Output files are written only after the computation succeeded, and a file
!! that fails to write completely is deleted.
program beamid_batch
    use, intrinsic :: iso_fortran_env, only: error_unit, output_unit
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK, ERR_IO, set_status
    use beamid_model, only: chain_t, chain_from_vector, param_name
    use beamid_deck, only: deck_t, read_deck
    use beamid_arclength, only: static_options_t, static_solution_t, solve_static, &
                                static_shape, NOUT
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_api_fe, only: api_fe_static, api_fe_modes
    implicit none

    character(len=*), parameter :: output_names(NOUT) = [character(len=11) :: &
        'x_tip', 'y_tip', 'tip_angle', 'wire_force', 'x_elbow', 'y_elbow', &
        'elbow_angle', 'root_moment']
    character(len=4096) :: arg
    type(deck_t) :: deck
    type(status_t) :: stat
    integer :: nargs

    nargs = command_argument_count()
    if (nargs /= 1) then
        write (error_unit, '(a)') 'usage: beamid-batch DECK   (a namelist deck, see docs/decks.md)'
        call exit_with(2)
    end if
    call get_command_argument(1, arg)
    if (trim(arg) == '-h' .or. trim(arg) == '--help') then
        write (output_unit, '(a)') 'usage: beamid-batch DECK'
        write (output_unit, '(a)') 'Runs a beamid namelist deck (docs/decks.md) and writes '// &
            '<output>_summary.csv and <output>_shape.csv next to the deck.'
        stop
    end if
    call read_deck(trim(arg), deck, stat)
    if (stat%code == STATUS_OK) then
        select case (deck%task)
        case ('fe_static')
            call run_fe_static(deck, stat)
        case ('fe_modes')
            call run_fe_modes(deck, stat)
        case default
            call run_static(deck, stat)
        end select
    end if
    if (stat%code /= STATUS_OK) then
        write (error_unit, '(a)') 'beamid-batch: error: '//trim(stat%message)
        if (stat%code == ERR_IO) call exit_with(4)
        if (stat%code < 0) call exit_with(2)
        call exit_with(3)
    end if

contains

    subroutine exit_with(code)
        integer, intent(in) :: code
        stop code, quiet=.true.
    end subroutine exit_with

    !> Output prefix resolved against the deck's directory.
    function output_prefix(d) result(prefix)
        type(deck_t), intent(in) :: d
        character(len=:), allocatable :: prefix
        integer :: slash
        if (d%output(1:1) == '/') then
            prefix = d%output
        else
            slash = index(d%path, '/', back=.true.)
            prefix = d%path(:slash)//d%output
        end if
    end function output_prefix

    subroutine run_static(d, st)
        type(deck_t), intent(in) :: d
        type(status_t), intent(inout) :: st
        type(chain_t) :: chain
        type(static_options_t) :: opts
        type(static_solution_t) :: sol
        real(dp), allocatable :: s(:), x(:), y(:), psi(:), moment(:)
        character(len=:), allocatable :: prefix
        integer :: i, j, n, unit, ios

        call chain_from_vector(d%nbeams, d%params, chain, st)
        if (st%code /= STATUS_OK) return
        if (d%tol > 0.0_dp) opts%tol = d%tol
        call solve_static(chain, d%load, d%wrt, opts, sol, st)
        if (st%code /= STATUS_OK) return
        n = d%shape_points
        allocate (s(n), x(n), y(n), psi(n), moment(n))
        if (n > 1) s = [(sum(chain%length)*real(i - 1, dp)/real(n - 1, dp), i = 1, n)]
        if (n > 1) then
            s(n) = sum(chain%length)
            call static_shape(chain, d%load, sol%unknowns, opts, s, x, y, psi, moment, st)
            if (st%code /= STATUS_OK) return
        end if

        prefix = output_prefix(d)
        call make_parent_folder(prefix, st)
        if (st%code /= STATUS_OK) return
        call open_output(prefix//'_summary.csv', 'quantity,value', unit, ios, st)
        if (st%code /= STATUS_OK) return
        do i = 1, NOUT
            if (ios == 0) write (unit, '(a,",",es24.16e3)', iostat=ios) trim(output_names(i)), &
                sol%outputs(i)
        end do
        do j = 1, size(d%wrt)
            do i = 1, NOUT
                if (ios == 0) write (unit, '(a,",",es24.16e3)', iostat=ios) &
                    'd('//trim(output_names(i))//')/d('//param_name(d%nbeams, d%wrt(j))//')', &
                    sol%doutputs(i, j)
            end do
        end do
        if (ios == 0) write (unit, '(a,",",i0)', iostat=ios) 'newton_iterations', &
            sol%newton_iterations
        if (ios == 0) write (unit, '(a,",",i0)', iostat=ios) 'load_steps', sol%load_steps
        call close_checked(unit, ios, prefix//'_summary.csv', st)
        if (st%code /= STATUS_OK) return

        if (n < 2) return
        call open_output(prefix//'_shape.csv', 's,x,y,psi,moment', unit, ios, st)
        if (st%code /= STATUS_OK) return
        do i = 1, n
            if (ios == 0) write (unit, '(4(es24.16e3,","),es24.16e3)', iostat=ios) &
                s(i), x(i), y(i), psi(i), moment(i)
        end do
        call close_checked(unit, ios, prefix//'_shape.csv', st)
    end subroutine run_static

    !> Finite element statics (docs/fe.md): tip values and the node table.
    subroutine run_fe_static(d, st)
        type(deck_t), intent(in) :: d
        type(status_t), intent(inout) :: st
        integer(c_int) :: nnode, info(2), code
        real(c_double), allocatable :: nodes(:, :), guess(:, :)
        real(c_double) :: energy, reactions(3), residual, loads(4)
        character(len=256) :: message
        character(len=:), allocatable :: prefix
        integer :: unit, ios, i
        real(dp) :: total, values(8)
        character(len=*), parameter :: names(8) = [character(len=8) :: 'w_tip', 'dw_tip', &
            'u_tip', 'du_tip', 'du_root', 'energy', 'x_tip', 'y_tip']

        nnode = int(d%nbeams*d%fe_elements_per_beam + 1, c_int)
        allocate (nodes(5, nnode), guess(5, nnode))
        guess = 0.0_c_double
        loads = [d%load%fx, d%load%fy, d%load%moment, real(d%fe_moment_form, dp)]
        call api_fe_static(int(d%nbeams, c_int), int(size(d%params), c_int), d%params, &
                           int(d%fe_elements_per_beam, c_int), nnode, loads, 0_c_int, &
                           int(d%fe_steps, c_int), d%fe_tol, guess, nodes, energy, reactions, &
                           residual, info, code, message)
        if (code /= 0) then
            call set_status(st, int(code), 'fe_static', trim(message))
            st%message = message
            return
        end if
        total = nodes(1, nnode)
        prefix = output_prefix(d)
        call make_parent_folder(prefix, st)
        if (st%code /= STATUS_OK) return
        call open_output(prefix//'_summary.csv', 'quantity,value', unit, ios, st)
        if (st%code /= STATUS_OK) return
        values = [nodes(4, nnode), nodes(5, nnode), nodes(2, nnode), nodes(3, nnode), &
                  nodes(3, 1), energy, total + nodes(2, nnode), nodes(4, nnode)]
        do i = 1, size(names)
            if (ios == 0) write (unit, '(a,",",es24.16e3)', iostat=ios) trim(names(i)), &
                values(i)
        end do
        if (ios == 0) write (unit, '(a,",",i0)', iostat=ios) 'newton_iterations', info(1)
        if (ios == 0) write (unit, '(a,",",i0)', iostat=ios) 'load_steps', info(2)
        call close_checked(unit, ios, prefix//'_summary.csv', st)
        if (st%code /= STATUS_OK) return
        call open_output(prefix//'_nodes.csv', 's,u,du,w,dw', unit, ios, st)
        if (st%code /= STATUS_OK) return
        do i = 1, nnode
            if (ios == 0) write (unit, '(4(es24.16e3,","),es24.16e3)', iostat=ios) nodes(:, i)
        end do
        call close_checked(unit, ios, prefix//'_nodes.csv', st)
    end subroutine run_fe_static

    !> Finite element linear modes: frequencies by family (Tables 9, 10).
    subroutine run_fe_modes(d, st)
        type(deck_t), intent(in) :: d
        type(status_t), intent(inout) :: st
        integer(c_int) :: nfree, code
        real(c_double), allocatable :: omega(:), phi(:, :)
        integer(c_int), allocatable :: axial(:), dofs(:, :)
        character(len=256) :: message
        character(len=:), allocatable :: prefix
        integer :: unit, ios, i, nw, nu

        ! four unknowns per node; the clamp (Eq. 103) fixes u, w and w' at the root
        nfree = int(4*(d%nbeams*d%fe_elements_per_beam + 1) - 3, c_int)
        allocate (omega(nfree), phi(nfree, nfree), axial(nfree), dofs(2, nfree))
        call api_fe_modes(int(d%nbeams, c_int), int(size(d%params), c_int), d%params, &
                          int(d%fe_elements_per_beam, c_int), merge(1_c_int, 0_c_int, &
                          d%fe_rotary_inertia), nfree, omega, phi, axial, dofs, code, message)
        if (code /= 0) then
            call set_status(st, int(code), 'fe_modes', trim(message))
            st%message = message
            return
        end if
        prefix = output_prefix(d)
        call make_parent_folder(prefix, st)
        if (st%code /= STATUS_OK) return
        call open_output(prefix//'_modes.csv', 'quantity,value', unit, ios, st)
        if (st%code /= STATUS_OK) return
        nw = 0
        nu = 0
        do i = 1, nfree
            if (axial(i) /= 0) then
                nu = nu + 1
                if (ios == 0) write (unit, '(a,i0,",",es24.16e3)', iostat=ios) 'omega_u', nu, &
                    omega(i)
            else
                nw = nw + 1
                if (ios == 0) write (unit, '(a,i0,",",es24.16e3)', iostat=ios) 'omega_w', nw, &
                    omega(i)
            end if
        end do
        call close_checked(unit, ios, prefix//'_modes.csv', st)
    end subroutine run_fe_modes

    !> Create the folder that will hold files starting with `prefix`.
    subroutine make_parent_folder(prefix, st)
        character(len=*), intent(in) :: prefix
        type(status_t), intent(inout) :: st
        integer :: slash, exitstat, cmdstat
        slash = index(prefix, '/', back=.true.)
        if (slash <= 1) return
        if (index(prefix, "'") > 0) then
            call set_status(st, ERR_IO, 'beamid-batch', 'output path may not contain a '// &
                            'quote: '//prefix)
            return
        end if
        call execute_command_line("mkdir -p '"//prefix(:slash - 1)//"'", exitstat=exitstat, &
                                  cmdstat=cmdstat)
        if (cmdstat /= 0 .or. exitstat /= 0) call set_status(st, ERR_IO, 'beamid-batch', &
            'cannot create the output folder '//prefix(:slash - 1))
    end subroutine make_parent_folder

    !> Open an output file for writing and write its header line.
    subroutine open_output(name, header, unit, ios, st)
        character(len=*), intent(in) :: name, header
        integer, intent(out) :: unit, ios
        type(status_t), intent(inout) :: st
        open (newunit=unit, file=name, status='replace', action='write', iostat=ios)
        if (ios /= 0) then
            call set_status(st, ERR_IO, 'beamid-batch', 'cannot write '//name)
            return
        end if
        write (unit, '(a)', iostat=ios) header
    end subroutine open_output

    !> Close a written file; delete it when any write failed.
    subroutine close_checked(unit, ios, name, st)
        integer, intent(in) :: unit, ios
        character(len=*), intent(in) :: name
        type(status_t), intent(inout) :: st
        if (ios /= 0) then
            close (unit, status='delete')
            call set_status(st, ERR_IO, 'beamid-batch', 'writing '//name//' failed')
        else
            close (unit)
        end if
    end subroutine close_checked
end program beamid_batch
