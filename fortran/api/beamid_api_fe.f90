!> f2py-facing API of the nonlinear finite element chain (Chapter IV).
!!
!! Plain arrays with c_int/c_double kinds, explicit shapes with their sizes,
!! and an integer status with a 256-character message. Every routine takes
!! the model as (nbeams, nparams, params) in the layout of beamid_model and
!! the mesh as elements_per_beam (nepb). Node tables have 5 rows per node:
!! s (undeformed arc length), u, u', w, w' (' = d/ds), nnode = nbeams*nepb + 1;
!! u', w' are the slopes of the element inboard of the node. Outboard tables
!! (2 rows per node: u'+, w'+) hold the slopes of the element outboard of the
!! node: they differ from u', w' only at a compliant joint (a hinge, whose
!! node carries a second slope pair); as inputs they may simply repeat rows
!! 3 and 5 of the node table. nfree depends on the compliances
!! (api_fe_mesh_sizes).
!! Loads are (fx, fy, moment, moment_form): a tip force of fixed direction
!! and a tip moment whose virtual work is Eq. 78 (moment_form 0) or the exact
!! delta Psi (moment_form 1).
module beamid_api_fe
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK, ERR_INPUT, set_status, fmt_int
    use beamid_model, only: chain_t, chain_from_vector
    use beamid_fe_element, only: FE_NDOF, fe_gauss_points, fe_quadrature_order, &
                                 fe_element_energy, fe_element_tangent, fe_element_mass
    use beamid_fe_assembly, only: fe_mesh_t, fe_load_t, fe_mesh_build, fe_band_rows, fe_tangent, &
                                  fe_band_to_dense, fe_mass, fe_energy, fe_tip_load, &
                                  fe_reactions, fe_node_value, DOF_W, DOF_DW, DOF_U, DOF_DU, &
                                  DOF_DW_OUT, DOF_DU_OUT, FE_MOMENT_EQ78, FE_MOMENT_EXACT
    use beamid_fe_static, only: fe_newton_opts_t, fe_solve_info_t, fe_solve_static, &
                                fe_residual, fe_path, fe_buckling_load
    use beamid_fe_modes, only: fe_modes, fe_modal_coordinates, fe_modal_cost, &
                               fe_axial_modes_linear
    implicit none
    private

    public :: api_fe_sizes, api_fe_static, api_fe_path, api_fe_buckling, api_fe_modes
    public :: api_fe_axial_linear, api_fe_modal_cost, api_fe_system, api_fe_element
    public :: api_fe_time_tangent, api_fe_mesh_sizes

contains

    !> Number of nodes and of free unknowns (after the clamp) of the mesh of a
    !! rigid chain (locked joints and clamp); api_fe_mesh_sizes for any chain.
    subroutine api_fe_sizes(nbeams, nepb, nnode, nfree)
        integer(c_int), intent(in) :: nbeams, nepb
        integer(c_int), intent(out) :: nnode, nfree
        nnode = nbeams*nepb + 1
        nfree = 4*nnode - 3
    end subroutine api_fe_sizes

    !> Number of nodes, free unknowns, compliant joints (hinges) and the
    !! half-bandwidth of the mesh of the model `params`.
    subroutine api_fe_mesh_sizes(nbeams, nparams, params, nepb, nnode, nfree, nhinge, band, &
                                 code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb
        real(c_double), intent(in) :: params(nparams)
        integer(c_int), intent(out) :: nnode, nfree, nhinge, band, code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(status_t) :: stat
        nnode = 0
        nfree = 0
        nhinge = 0
        band = 0
        call make_mesh(nbeams, nparams, params, nepb, nbeams*nepb + 1, mesh, stat)
        if (stat%code == STATUS_OK) then
            nnode = int(mesh%nnode, c_int)
            nfree = int(mesh%nfree, c_int)
            nhinge = int(mesh%nhinge, c_int)
            band = int(mesh%kl, c_int)
        end if
        code = int(stat%code, c_int)
        message = stat%message
    end subroutine api_fe_mesh_sizes

    !> Chain and mesh from the API arguments, checking the node count.
    subroutine make_mesh(nbeams, nparams, params, nepb, nnode, mesh, stat)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, nnode
        real(c_double), intent(in) :: params(nparams)
        type(fe_mesh_t), intent(out) :: mesh
        type(status_t), intent(inout) :: stat
        type(chain_t) :: chain
        call chain_from_vector(int(nbeams), real(params, dp), chain, stat)
        if (stat%code /= STATUS_OK) return
        call fe_mesh_build(chain, int(nepb), mesh, stat)
        if (stat%code /= STATUS_OK) return
        if (mesh%nnode /= nnode) then
            call set_status(stat, ERR_INPUT, 'beamid_api_fe', 'nnode = '//fmt_int(int(nnode))// &
                            ', expected nbeams*elements_per_beam + 1 = '//fmt_int(mesh%nnode))
        end if
    end subroutine make_mesh

    subroutine make_load(values, load, stat)
        real(c_double), intent(in) :: values(4)
        type(fe_load_t), intent(out) :: load
        type(status_t), intent(inout) :: stat
        load%fx = values(1)
        load%fy = values(2)
        load%moment = values(3)
        load%moment_form = nint(values(4))
        if (load%moment_form /= FE_MOMENT_EQ78 .and. load%moment_form /= FE_MOMENT_EXACT) then
            call set_status(stat, ERR_INPUT, 'beamid_api_fe', 'moment_form = '// &
                            fmt_int(load%moment_form)//', expected 0 (Eq. 78) or 1 (exact)')
        end if
    end subroutine make_load

    subroutine make_options(nsteps, tol, opts, stat)
        integer(c_int), intent(in) :: nsteps
        real(c_double), intent(in) :: tol
        type(fe_newton_opts_t), intent(out) :: opts
        type(status_t), intent(inout) :: stat
        if (nsteps > 0) opts%nsteps = int(nsteps)
        if (tol > 0.0_c_double) opts%tol = tol
        if (nsteps < 0 .or. tol < 0.0_c_double) then
            call set_status(stat, ERR_INPUT, 'beamid_api_fe', 'nsteps = '// &
                            fmt_int(int(nsteps))//' and tol must not be negative (0: default)')
        end if
    end subroutine make_options

    !> Free vector q from a node table (rows s, u, u', w, w'); s is ignored.
    !! The outboard slopes of a hinge come from `outboard` (rows u'+, w'+)
    !! when present, else they start equal to the inboard ones.
    subroutine q_from_nodes(mesh, nodes, q, outboard)
        type(fe_mesh_t), intent(in) :: mesh
        real(c_double), intent(in) :: nodes(:, :)
        real(dp), intent(out) :: q(:)
        real(c_double), intent(in), optional :: outboard(:, :)
        integer :: k, node
        do k = 1, mesh%nfree
            node = mesh%free_node(k)
            select case (mesh%free_comp(k))
            case (DOF_W)
                q(k) = nodes(4, node)
            case (DOF_DW)
                q(k) = nodes(5, node)
            case (DOF_U)
                q(k) = nodes(2, node)
            case (DOF_DU)
                q(k) = nodes(3, node)
            case (DOF_DW_OUT)
                q(k) = nodes(5, node)
                if (present(outboard)) q(k) = outboard(2, node)
            case (DOF_DU_OUT)
                q(k) = nodes(3, node)
                if (present(outboard)) q(k) = outboard(1, node)
            end select
        end do
    end subroutine q_from_nodes

    !> Node table (rows s, u, u', w, w') from the free vector q and, optionally,
    !! the outboard slopes (rows u'+, w'+; equal to u', w' except at a hinge).
    subroutine nodes_from_q(mesh, q, nodes, outboard)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        real(c_double), intent(out) :: nodes(:, :)
        real(c_double), intent(out), optional :: outboard(:, :)
        integer :: node
        do node = 1, mesh%nnode
            nodes(1, node) = mesh%s(node)
            nodes(2, node) = fe_node_value(mesh, q, node, DOF_U)
            nodes(3, node) = fe_node_value(mesh, q, node, DOF_DU)
            nodes(4, node) = fe_node_value(mesh, q, node, DOF_W)
            nodes(5, node) = fe_node_value(mesh, q, node, DOF_DW)
            if (present(outboard)) then
                outboard(1, node) = fe_node_value(mesh, q, node, DOF_DU_OUT)
                outboard(2, node) = fe_node_value(mesh, q, node, DOF_DW_OUT)
            end if
        end do
    end subroutine nodes_from_q

    !> Static equilibrium (Eq. 83-85). use_guess = 1 starts Newton at the full
    !! load from the shape in `guess` (outboard slopes `guess_out`); 0 steps
    !! the load up from the straight chain in nsteps initial steps (0:
    !! default). Outputs the node table, the outboard slopes, the strain
    !! energy (springs included), the root reactions (Lagrange multipliers of
    !! Eq. 105 on w, w', u) and info = (Newton iterations, accepted load steps,
    !! negative eigenvalues of the tangent: 0 stable, >= 1 unstable).
    subroutine api_fe_static(nbeams, nparams, params, nepb, nnode, loads, use_guess, nsteps, &
                             tol, guess, guess_out, nodes, nodes_out, energy, reactions, &
                             residual, info, code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, nnode, use_guess, nsteps
        real(c_double), intent(in) :: params(nparams), loads(4), tol, guess(5, nnode)
        real(c_double), intent(in) :: guess_out(2, nnode)
        real(c_double), intent(out) :: nodes(5, nnode), nodes_out(2, nnode)
        real(c_double), intent(out) :: energy, reactions(3), residual
        integer(c_int), intent(out) :: info(3), code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(fe_load_t) :: load
        type(fe_newton_opts_t) :: opts
        type(fe_solve_info_t) :: sinfo
        type(status_t) :: stat
        real(dp), allocatable :: q(:)
        real(dp) :: r3(3)
        nodes = 0.0_c_double
        nodes_out = 0.0_c_double
        energy = 0.0_c_double
        reactions = 0.0_c_double
        residual = 0.0_c_double
        info = 0
        call make_mesh(nbeams, nparams, params, nepb, nnode, mesh, stat)
        if (stat%code == STATUS_OK) call make_load(loads, load, stat)
        if (stat%code == STATUS_OK) call make_options(nsteps, tol, opts, stat)
        if (stat%code == STATUS_OK) then
            allocate (q(mesh%nfree))
            q = 0.0_dp
            if (use_guess /= 0) call q_from_nodes(mesh, guess, q, guess_out)
            call fe_solve_static(mesh, load, q, use_guess /= 0, opts, sinfo, stat)
            info = int([sinfo%iterations, sinfo%steps, sinfo%negative], c_int)
            residual = sinfo%residual
            if (stat%code == STATUS_OK) then
                call nodes_from_q(mesh, q, nodes, nodes_out)
                energy = fe_energy(mesh, q)
                call fe_reactions(mesh, q, r3)
                reactions = r3
            end if
        end if
        code = int(stat%code, c_int)
        message = stat%message
    end subroutine api_fe_static

    !> Pseudo-arc-length path of equilibria under load0 + lam * dload (dload =
    !! (dfx, dfy, dmoment), moment form from load0), from the equilibrium near
    !! `guess` (outboard slopes `guess_out`) at lam0. Returns npts <= maxpts
    !! points: lam, node tables and outboard slopes.
    subroutine api_fe_path(nbeams, nparams, params, nepb, nnode, load0, dload, guess, &
                           guess_out, lam0, ds, ds_max, direction, lam_min, lam_max, tol, &
                           maxpts, npts, lam, nodes, nodes_out, code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, nnode, direction, maxpts
        real(c_double), intent(in) :: params(nparams), load0(4), dload(3), guess(5, nnode)
        real(c_double), intent(in) :: guess_out(2, nnode)
        real(c_double), intent(in) :: lam0, ds, ds_max, lam_min, lam_max, tol
        integer(c_int), intent(out) :: npts, code
        real(c_double), intent(out) :: lam(maxpts), nodes(5, nnode, maxpts)
        real(c_double), intent(out) :: nodes_out(2, nnode, maxpts)
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(fe_load_t) :: l0, dl
        type(fe_newton_opts_t) :: opts
        type(status_t) :: stat
        real(dp), allocatable :: q(:), qout(:, :), lout(:)
        integer :: i, n
        npts = 0
        lam = 0.0_c_double
        nodes = 0.0_c_double
        nodes_out = 0.0_c_double
        call make_mesh(nbeams, nparams, params, nepb, nnode, mesh, stat)
        if (stat%code == STATUS_OK) call make_load(load0, l0, stat)
        if (stat%code == STATUS_OK) call make_options(0_c_int, tol, opts, stat)
        if (stat%code == STATUS_OK .and. maxpts < 1) then
            call set_status(stat, ERR_INPUT, 'api_fe_path', 'maxpts = '// &
                            fmt_int(int(maxpts))//', expected at least 1')
        end if
        if (stat%code == STATUS_OK) then
            dl = l0
            dl%fx = dload(1)
            dl%fy = dload(2)
            dl%moment = dload(3)
            allocate (q(mesh%nfree), qout(mesh%nfree, maxpts), lout(maxpts))
            call q_from_nodes(mesh, guess, q, guess_out)
            call fe_path(mesh, l0, dl, q, lam0, ds, ds_max, int(direction), lam_min, lam_max, &
                         opts, n, lout, qout, stat)
            npts = int(n, c_int)
            do i = 1, n
                lam(i) = lout(i)
                call nodes_from_q(mesh, qout(:, i), nodes(:, :, i), nodes_out(:, :, i))
            end do
        end if
        code = int(stat%code, c_int)
        message = stat%message
    end subroutine api_fe_path

    !> Linear buckling load of the straight chain under a compressive tip force
    !! and its mode (node table and outboard slopes, tip w = 1).
    subroutine api_fe_buckling(nbeams, nparams, params, nepb, nnode, pcr, mode, mode_out, code, &
                               message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, nnode
        real(c_double), intent(in) :: params(nparams)
        real(c_double), intent(out) :: pcr, mode(5, nnode), mode_out(2, nnode)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(status_t) :: stat
        real(dp), allocatable :: q(:)
        real(dp) :: p
        pcr = 0.0_c_double
        mode = 0.0_c_double
        mode_out = 0.0_c_double
        call make_mesh(nbeams, nparams, params, nepb, nnode, mesh, stat)
        if (stat%code == STATUS_OK) then
            allocate (q(mesh%nfree))
            call fe_buckling_load(mesh, p, q, stat)
            if (stat%code == STATUS_OK) then
                pcr = p
                call nodes_from_q(mesh, q, mode, mode_out)
            end if
        end if
        code = int(stat%code, c_int)
        message = stat%message
    end subroutine api_fe_buckling

    !> Linear modes (Eq. 124-126): omega ascending (rad/s), mass-normalized
    !! shapes phi (columns over the free unknowns), axial(i) = 1 for a u mode,
    !! and dofs(:, k) = (node, component) of free unknown k: 1..4 = w, w', u,
    !! u', and at a hinge 5, 6 = the outboard w'+, u'+.
    subroutine api_fe_modes(nbeams, nparams, params, nepb, rotary, nfree, omega, phi, axial, &
                            dofs, code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, rotary, nfree
        real(c_double), intent(in) :: params(nparams)
        real(c_double), intent(out) :: omega(nfree), phi(nfree, nfree)
        integer(c_int), intent(out) :: axial(nfree), dofs(2, nfree), code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(status_t) :: stat
        real(dp), allocatable :: om(:), ph(:, :)
        logical, allocatable :: ax(:)
        integer :: k
        omega = 0.0_c_double
        phi = 0.0_c_double
        axial = 0
        dofs = 0
        call make_mesh(nbeams, nparams, params, nepb, nbeams*nepb + 1, mesh, stat)
        if (stat%code == STATUS_OK .and. mesh%nfree /= nfree) then
            call set_status(stat, ERR_INPUT, 'api_fe_modes', 'nfree = '//fmt_int(int(nfree))// &
                            ', expected '//fmt_int(mesh%nfree))
        end if
        if (stat%code == STATUS_OK) then
            allocate (om(nfree), ph(nfree, nfree), ax(nfree))
            call fe_modes(mesh, rotary /= 0, om, ph, ax, stat)
            if (stat%code == STATUS_OK) then
                omega = om
                phi = ph
                axial = merge(1_c_int, 0_c_int, ax)
                do k = 1, nfree
                    dofs(1, k) = int(mesh%free_node(k), c_int)
                    dofs(2, k) = int(mesh%free_comp(k), c_int)
                end do
            end if
        end if
        code = int(stat%code, c_int)
        message = stat%message
    end subroutine api_fe_modes

    !> Axial frequencies of the linear-u verification model (Eq. 114, Table 7).
    subroutine api_fe_axial_linear(nbeams, nparams, params, nepb, point_masses, nel, omega, &
                                   code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, point_masses, nel
        real(c_double), intent(in) :: params(nparams)
        real(c_double), intent(out) :: omega(nel)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(status_t) :: stat
        real(dp), allocatable :: om(:)
        omega = 0.0_c_double
        call make_mesh(nbeams, nparams, params, nepb, nel + 1, mesh, stat)
        if (stat%code == STATUS_OK) then
            allocate (om(nel))
            call fe_axial_modes_linear(mesh, point_masses /= 0, om, stat)
            if (stat%code == STATUS_OK) omega = om
        end if
        code = int(stat%code, c_int)
        message = stat%message
    end subroutine api_fe_axial_linear

    !> Skelton's modal cost (Eq. 127-128) of the linear free vibration from the
    !! shape `shape0` and velocity `vel0` (node tables, outboard slopes in
    !! shape0_out, vel0_out) over [0, t]: modal
    !! coordinates eta = Phi^T M q, and per mode the kinetic and potential
    !! integrals (ascending frequency order, as api_fe_modes).
    subroutine api_fe_modal_cost(nbeams, nparams, params, nepb, rotary, nnode, nfree, shape0, &
                                 shape0_out, vel0, vel0_out, t, omega, eta, kinetic, potential, &
                                 code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, rotary, nnode, nfree
        real(c_double), intent(in) :: params(nparams), shape0(5, nnode), vel0(5, nnode), t
        real(c_double), intent(in) :: shape0_out(2, nnode), vel0_out(2, nnode)
        real(c_double), intent(out) :: omega(nfree), eta(nfree), kinetic(nfree), potential(nfree)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(status_t) :: stat
        real(dp), allocatable :: om(:), ph(:, :), q(:), v(:), e0(:), ed0(:), kin(:), pot(:)
        logical, allocatable :: ax(:)
        omega = 0.0_c_double
        eta = 0.0_c_double
        kinetic = 0.0_c_double
        potential = 0.0_c_double
        call make_mesh(nbeams, nparams, params, nepb, nnode, mesh, stat)
        if (stat%code == STATUS_OK .and. mesh%nfree /= nfree) then
            call set_status(stat, ERR_INPUT, 'api_fe_modal_cost', 'nfree = '// &
                            fmt_int(int(nfree))//', expected '//fmt_int(mesh%nfree))
        end if
        if (stat%code == STATUS_OK .and. .not. (t > 0.0_c_double)) then
            call set_status(stat, ERR_INPUT, 'api_fe_modal_cost', 'time span t must be positive')
        end if
        if (stat%code == STATUS_OK) then
            allocate (om(nfree), ph(nfree, nfree), ax(nfree), q(nfree), v(nfree), e0(nfree), &
                      ed0(nfree), kin(nfree), pot(nfree))
            call fe_modes(mesh, rotary /= 0, om, ph, ax, stat)
            if (stat%code == STATUS_OK) then
                call q_from_nodes(mesh, shape0, q, shape0_out)
                call q_from_nodes(mesh, vel0, v, vel0_out)
                call fe_modal_coordinates(mesh, rotary /= 0, ph, q, e0, stat)
            end if
            if (stat%code == STATUS_OK) then
                call fe_modal_coordinates(mesh, rotary /= 0, ph, v, ed0, stat)
            end if
            if (stat%code == STATUS_OK) then
                call fe_modal_cost(om, e0, ed0, real(t, dp), kin, pot)
                omega = om
                eta = e0
                kinetic = kin
                potential = pot
            end if
        end if
        code = int(stat%code, c_int)
        message = stat%message
    end subroutine api_fe_modal_cost

    !> Dense system at the free vector q (for checks): strain energy, internal
    !! force NLT(q), the Newton matrix d(NLT - Q)/dq, the mass matrix (rotary
    !! inertia of Eq. 132 with rotary = 1) and the tip load vector Q(q).
    subroutine api_fe_system(nbeams, nparams, params, nepb, rotary, nfree, q, loads, energy, &
                             force, jac, mass, qload, code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, rotary, nfree
        real(c_double), intent(in) :: params(nparams), q(nfree), loads(4)
        real(c_double), intent(out) :: energy, force(nfree), jac(nfree, nfree)
        real(c_double), intent(out) :: mass(nfree, nfree), qload(nfree)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(fe_load_t) :: load
        type(status_t) :: stat
        real(dp), allocatable :: qd(:), r(:), jb(:, :), mb(:, :), qv(:), a(:, :)
        energy = 0.0_c_double
        force = 0.0_c_double
        jac = 0.0_c_double
        mass = 0.0_c_double
        qload = 0.0_c_double
        call make_mesh(nbeams, nparams, params, nepb, nbeams*nepb + 1, mesh, stat)
        if (stat%code == STATUS_OK .and. mesh%nfree /= nfree) then
            call set_status(stat, ERR_INPUT, 'api_fe_system', 'nfree = '//fmt_int(int(nfree))// &
                            ', expected '//fmt_int(mesh%nfree))
        end if
        if (stat%code == STATUS_OK) call make_load(loads, load, stat)
        if (stat%code == STATUS_OK) then
            allocate (qd(nfree), r(nfree), jb(fe_band_rows(mesh), nfree), &
                      mb(fe_band_rows(mesh), nfree), qv(nfree), a(nfree, nfree))
            qd = q
            call fe_residual(mesh, load, qd, r, jb)
            call fe_tip_load(mesh, qd, load, qv)
            force = r + qv
            qload = qv
            call fe_band_to_dense(jb, mesh%kl, mesh%ku, a)
            jac = a
            call fe_mass(mesh, qd, rotary /= 0, mb)
            call fe_band_to_dense(mb, mesh%kl, mesh%ku, a)
            mass = a
            energy = fe_energy(mesh, qd)
        end if
        code = int(stat%code, c_int)
        message = stat%message
    end subroutine api_fe_system

    !> One element (for checks): energy, internal force, tangent and mass with
    !! the exact Gauss rule, element unknowns [w1, w1', u1, u1', w2, w2', u2, u2'].
    subroutine api_fe_element(h, ea, ei, cubic, rho, qe, energy, force, tangent, mass)
        real(c_double), intent(in) :: h, ea, ei, cubic, rho, qe(8)
        real(c_double), intent(out) :: energy, force(8), tangent(8, 8), mass(8, 8)
        real(dp), allocatable :: xg(:), wg(:)
        real(dp) :: f(FE_NDOF), k(FE_NDOF, FE_NDOF), m(FE_NDOF, FE_NDOF), q(FE_NDOF)
        integer :: n
        n = fe_quadrature_order(real(cubic, dp))
        allocate (xg(n), wg(n))
        call fe_gauss_points(n, xg, wg)
        q = qe
        energy = fe_element_energy(real(h, dp), real(ea, dp), real(ei, dp), real(cubic, dp), &
                                   xg, wg, q)
        call fe_element_tangent(real(h, dp), real(ea, dp), real(ei, dp), real(cubic, dp), &
                                xg, wg, q, f, k)
        call fe_element_mass(real(h, dp), real(rho, dp), m)
        force = f
        tangent = k
        mass = m
    end subroutine api_fe_element

    !> Wall-clock seconds of nrep banded tangent assemblies (internal force and
    !! K_T) at a fixed bent state, for `make bench`.
    subroutine api_fe_time_tangent(nbeams, nparams, params, nepb, nrep, seconds, code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nepb, nrep
        real(c_double), intent(in) :: params(nparams)
        real(c_double), intent(out) :: seconds
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(status_t) :: stat
        real(dp), allocatable :: q(:), f(:), kb(:, :)
        integer(kind=8) :: t0, t1, rate
        integer :: i
        seconds = 0.0_c_double
        call make_mesh(nbeams, nparams, params, nepb, nbeams*nepb + 1, mesh, stat)
        if (stat%code == STATUS_OK .and. nrep < 1) then
            call set_status(stat, ERR_INPUT, 'api_fe_time_tangent', 'nrep = '// &
                            fmt_int(int(nrep))//', expected at least 1')
        end if
        if (stat%code == STATUS_OK) then
            allocate (q(mesh%nfree), f(mesh%nfree), kb(fe_band_rows(mesh), mesh%nfree))
            do i = 1, mesh%nfree
                q(i) = 1.0e-2_dp*sin(real(i, dp))
            end do
            call system_clock(t0, rate)
            do i = 1, nrep
                call fe_tangent(mesh, q, f, kb)
                q(1) = q(1) + 1.0e-3_dp*f(1)/max(1.0_dp, abs(f(1)))   ! keep the loop honest
            end do
            call system_clock(t1)
            seconds = real(t1 - t0, dp)/real(rate, dp)
        end if
        code = int(stat%code, c_int)
        message = stat%message
    end subroutine api_fe_time_tangent

end module beamid_api_fe
