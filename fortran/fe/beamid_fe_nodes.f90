!> The finite element chain (Chapter IV) as both fronts call it: the mesh of
!! a parameter vector, loads and Newton options from plain values, node
!! tables, and the solves that take and return node tables (beamid_api_fe
!! binds them for Python, beamid_tasks runs them for the decks).
!!
!! Node tables have 5 rows per node: s (undeformed arc length), u, u', w, w'
!! (' = d/ds), nnode = nbeams*elements_per_beam + 1; u', w' are the slopes of
!! the element inboard of the node. Outboard tables (2 rows per node: u'+,
!! w'+) hold the slopes of the element outboard of the node: they differ from
!! u', w' only at a compliant joint (a hinge, whose node carries a second
!! slope pair); as inputs they may simply repeat rows 3 and 5 of the node
!! table. Loads are (fx, fy, moment, moment_form): a tip force of fixed
!! direction and a tip moment whose virtual work is Eq. 78 (moment_form 0)
!! or the exact delta Psi (moment_form 1).
module beamid_fe_nodes
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK, ERR_INPUT, set_status, fmt_int
    use beamid_model, only: chain_t, chain_from_vector
    use beamid_fe_assembly, only: fe_mesh_t, fe_load_t, fe_mesh_build, fe_band_rows, &
                                  fe_mass, fe_energy, fe_tip_load, &
                                  fe_reactions, fe_node_value, DOF_W, DOF_DW, DOF_U, DOF_DU, &
                                  DOF_DW_OUT, DOF_DU_OUT, FE_MOMENT_EQ78, FE_MOMENT_EXACT
    use beamid_fe_static, only: fe_newton_opts_t, fe_solve_info_t, fe_solve_static, &
                                fe_residual, fe_path, fe_buckling_load
    use beamid_fe_modes, only: fe_modes, fe_modal_coordinates, fe_modal_cost
    use beamid_band, only: band_to_dense
    implicit none
    private

    public :: fe_mesh_from_params, fe_load_from_values, fe_newton_options, fe_setup
    public :: fe_static_nodes, fe_path_nodes, fe_buckling_nodes, fe_modes_table
    public :: fe_modal_cost_nodes, fe_system_dense

contains

    !> Chain and mesh of the parameter vector `params` of nbeams beams with
    !! elements_per_beam elements on each; a caller's node count `nnode`
    !! (when given) must be the mesh's.
    subroutine fe_mesh_from_params(nbeams, params, elements_per_beam, mesh, stat, nnode)
        integer, intent(in) :: nbeams, elements_per_beam
        real(dp), intent(in) :: params(:)
        type(fe_mesh_t), intent(out) :: mesh
        type(status_t), intent(inout) :: stat
        integer, intent(in), optional :: nnode
        type(chain_t) :: chain
        call chain_from_vector(nbeams, params, chain, stat)
        if (stat%code /= STATUS_OK) return
        call fe_mesh_build(chain, elements_per_beam, mesh, stat)
        if (stat%code /= STATUS_OK .or. .not. present(nnode)) return
        if (mesh%nnode /= nnode) then
            call set_status(stat, ERR_INPUT, 'beamid_api_fe', 'nnode = '//fmt_int(nnode)// &
                            ', expected nbeams*elements_per_beam + 1 = '//fmt_int(mesh%nnode))
        end if
    end subroutine fe_mesh_from_params

    !> Tip load from (fx, fy, moment, moment_form).
    subroutine fe_load_from_values(values, load, stat)
        real(dp), intent(in) :: values(4)
        type(fe_load_t), intent(out) :: load
        type(status_t), intent(inout) :: stat
        load = fe_load_t(values(1), values(2), values(3), nint(values(4)))
        if (load%moment_form /= FE_MOMENT_EQ78 .and. load%moment_form /= FE_MOMENT_EXACT) then
            call set_status(stat, ERR_INPUT, 'beamid_api_fe', 'moment_form = '// &
                            fmt_int(load%moment_form)//', expected 0 (Eq. 78) or 1 (exact)')
        end if
    end subroutine fe_load_from_values

    !> Newton options: nsteps initial load steps and tolerance tol (0: default).
    subroutine fe_newton_options(nsteps, tol, opts, stat)
        integer, intent(in) :: nsteps
        real(dp), intent(in) :: tol
        type(fe_newton_opts_t), intent(out) :: opts
        type(status_t), intent(inout) :: stat
        if (nsteps > 0) opts%nsteps = nsteps
        if (tol > 0.0_dp) opts%tol = tol
        if (nsteps < 0 .or. tol < 0.0_dp) then
            call set_status(stat, ERR_INPUT, 'beamid_api_fe', 'nsteps = '// &
                            fmt_int(nsteps)//' and tol must not be negative (0: default)')
        end if
    end subroutine fe_newton_options

    !> Mesh, tip load (fx, fy, moment, moment_form) and Newton options (nsteps,
    !! tol; 0: defaults) of a static problem, checking the caller's nnode.
    subroutine fe_setup(nbeams, params, elements_per_beam, values, nsteps, tol, mesh, load, &
                        opts, stat, nnode)
        integer, intent(in) :: nbeams, elements_per_beam, nsteps
        real(dp), intent(in) :: params(:), values(4), tol
        type(fe_mesh_t), intent(out) :: mesh
        type(fe_load_t), intent(out) :: load
        type(fe_newton_opts_t), intent(out) :: opts
        type(status_t), intent(inout) :: stat
        integer, intent(in), optional :: nnode
        call fe_mesh_from_params(nbeams, params, elements_per_beam, mesh, stat, nnode)
        if (stat%code == STATUS_OK) call fe_load_from_values(values, load, stat)
        if (stat%code == STATUS_OK) call fe_newton_options(nsteps, tol, opts, stat)
    end subroutine fe_setup

    !> Free vector q from a node table (rows s, u, u', w, w'); s is ignored.
    !! The outboard slopes of a hinge come from `outboard` (rows u'+, w'+)
    !! when present, else they start equal to the inboard ones.
    pure subroutine fe_q_from_nodes(mesh, nodes, q, outboard)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: nodes(:, :)
        real(dp), intent(out) :: q(:)
        real(dp), intent(in), optional :: outboard(:, :)
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
    end subroutine fe_q_from_nodes

    !> Node table (rows s, u, u', w, w') from the free vector q and, optionally,
    !! the outboard slopes (rows u'+, w'+; equal to u', w' except at a hinge).
    pure subroutine fe_nodes_from_q(mesh, q, nodes, outboard)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: nodes(:, :)
        real(dp), intent(out), optional :: outboard(:, :)
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
    end subroutine fe_nodes_from_q

    !> Static equilibrium (Eq. 83-85). from_guess starts Newton at the full
    !! load from the shape in `guess` (outboard slopes `guess_out`); else the
    !! load is stepped up from the straight chain. Outputs the node table, the
    !! outboard slopes, the strain energy (springs included), the root
    !! reactions (Lagrange multipliers of Eq. 105 on w, w', u) and info =
    !! (Newton iterations, accepted load steps, negative eigenvalues of the
    !! tangent: 0 stable, >= 1 unstable).
    subroutine fe_static_nodes(mesh, load, from_guess, opts, guess, guess_out, nodes, &
                               nodes_out, energy, reactions, residual, info, stat)
        type(fe_mesh_t), intent(in) :: mesh
        type(fe_load_t), intent(in) :: load
        logical, intent(in) :: from_guess
        type(fe_newton_opts_t), intent(in) :: opts
        real(dp), intent(in) :: guess(:, :), guess_out(:, :)
        real(dp), intent(out) :: nodes(:, :), nodes_out(:, :), energy, reactions(3), residual
        integer, intent(out) :: info(3)
        type(status_t), intent(inout) :: stat
        type(fe_solve_info_t) :: sinfo
        real(dp), allocatable :: q(:)
        nodes = 0.0_dp
        nodes_out = 0.0_dp
        energy = 0.0_dp
        reactions = 0.0_dp
        allocate (q(mesh%nfree), source=0.0_dp)
        if (from_guess) call fe_q_from_nodes(mesh, guess, q, guess_out)
        call fe_solve_static(mesh, load, q, from_guess, opts, sinfo, stat)
        info = [sinfo%iterations, sinfo%steps, sinfo%negative]
        residual = sinfo%residual
        if (stat%code /= STATUS_OK) return
        call fe_nodes_from_q(mesh, q, nodes, nodes_out)
        energy = fe_energy(mesh, q)
        call fe_reactions(mesh, q, reactions)
    end subroutine fe_static_nodes

    !> Pseudo-arc-length path of equilibria under load0 + lam * dload (dload =
    !! (dfx, dfy, dmoment), moment form from load0), from the equilibrium near
    !! `guess` (outboard slopes `guess_out`) at lam0. Returns npts <=
    !! size(lam) points: lam, node tables and outboard slopes.
    subroutine fe_path_nodes(mesh, load0, dload, guess, guess_out, lam0, ds, ds_max, &
                             direction, lam_min, lam_max, opts, npts, lam, nodes, nodes_out, stat)
        type(fe_mesh_t), intent(in) :: mesh
        type(fe_load_t), intent(in) :: load0
        real(dp), intent(in) :: dload(3), guess(:, :), guess_out(:, :)
        real(dp), intent(in) :: lam0, ds, ds_max, lam_min, lam_max
        integer, intent(in) :: direction
        type(fe_newton_opts_t), intent(in) :: opts
        integer, intent(out) :: npts
        real(dp), intent(out) :: lam(:), nodes(:, :, :), nodes_out(:, :, :)
        type(status_t), intent(inout) :: stat
        type(fe_load_t) :: dl
        real(dp), allocatable :: q(:), qout(:, :)
        integer :: i, maxpts
        npts = 0
        lam = 0.0_dp
        nodes = 0.0_dp
        nodes_out = 0.0_dp
        maxpts = size(lam)
        if (maxpts < 1) then
            call set_status(stat, ERR_INPUT, 'api_fe_path', 'maxpts = '// &
                            fmt_int(maxpts)//', expected at least 1')
            return
        end if
        dl = fe_load_t(dload(1), dload(2), dload(3), load0%moment_form)
        allocate (q(mesh%nfree), qout(mesh%nfree, maxpts))
        call fe_q_from_nodes(mesh, guess, q, guess_out)
        call fe_path(mesh, load0, dl, q, lam0, ds, ds_max, direction, lam_min, lam_max, &
                     opts, npts, lam, qout, stat)
        do i = 1, npts
            call fe_nodes_from_q(mesh, qout(:, i), nodes(:, :, i), nodes_out(:, :, i))
        end do
    end subroutine fe_path_nodes

    !> Linear buckling load of the straight chain under a compressive tip force
    !! and its mode (node table and outboard slopes, tip w = 1).
    subroutine fe_buckling_nodes(mesh, pcr, mode, mode_out, stat)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(out) :: pcr, mode(:, :), mode_out(:, :)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: q(:)
        pcr = 0.0_dp
        mode = 0.0_dp
        mode_out = 0.0_dp
        allocate (q(mesh%nfree))
        call fe_buckling_load(mesh, pcr, q, stat)
        if (stat%code == STATUS_OK) call fe_nodes_from_q(mesh, q, mode, mode_out)
    end subroutine fe_buckling_nodes

    !> A caller's count of free unknowns `nfree` must be the mesh's.
    subroutine check_nfree(mesh, nfree, where, stat)
        type(fe_mesh_t), intent(in) :: mesh
        integer, intent(in) :: nfree
        character(len=*), intent(in) :: where
        type(status_t), intent(inout) :: stat
        if (mesh%nfree /= nfree) then
            call set_status(stat, ERR_INPUT, where, 'nfree = '//fmt_int(nfree)// &
                            ', expected '//fmt_int(mesh%nfree))
        end if
    end subroutine check_nfree

    !> Linear modes (Eq. 124-126): omega ascending (rad/s), mass-normalized
    !! shapes phi (columns over the free unknowns), axial(i) = 1 for a u mode,
    !! and dofs(:, k) = (node, component) of free unknown k: 1..4 = w, w', u,
    !! u', and at a hinge 5, 6 = the outboard w'+, u'+.
    subroutine fe_modes_table(mesh, rotary, omega, phi, axial, dofs, stat)
        type(fe_mesh_t), intent(in) :: mesh
        logical, intent(in) :: rotary
        real(dp), intent(out) :: omega(:), phi(:, :)
        integer, intent(out) :: axial(:), dofs(:, :)
        type(status_t), intent(inout) :: stat
        logical, allocatable :: ax(:)
        omega = 0.0_dp
        phi = 0.0_dp
        axial = 0
        dofs = 0
        call check_nfree(mesh, size(omega), 'api_fe_modes', stat)
        if (stat%code /= STATUS_OK) return
        allocate (ax(mesh%nfree))
        call fe_modes(mesh, rotary, omega, phi, ax, stat)
        if (stat%code /= STATUS_OK) return
        axial = merge(1, 0, ax)
        dofs(1, :) = mesh%free_node
        dofs(2, :) = mesh%free_comp
    end subroutine fe_modes_table

    !> Skelton's modal cost (Eq. 127-128) of the linear free vibration from the
    !! shape `shape0` and velocity `vel0` (node tables, outboard slopes in
    !! shape0_out, vel0_out) over [0, t]: modal coordinates eta = Phi^T M q,
    !! and per mode the kinetic and potential integrals (ascending frequency
    !! order, as fe_modes_table).
    subroutine fe_modal_cost_nodes(mesh, rotary, shape0, shape0_out, vel0, vel0_out, t, omega, &
                                   eta, kinetic, potential, stat)
        type(fe_mesh_t), intent(in) :: mesh
        logical, intent(in) :: rotary
        real(dp), intent(in) :: shape0(:, :), shape0_out(:, :), vel0(:, :), vel0_out(:, :), t
        real(dp), intent(out) :: omega(:), eta(:), kinetic(:), potential(:)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: phi(:, :), q(:), v(:), etadot(:)
        logical, allocatable :: ax(:)
        integer :: n
        omega = 0.0_dp
        eta = 0.0_dp
        kinetic = 0.0_dp
        potential = 0.0_dp
        call check_nfree(mesh, size(omega), 'api_fe_modal_cost', stat)
        if (stat%code == STATUS_OK .and. .not. (t > 0.0_dp)) then
            call set_status(stat, ERR_INPUT, 'api_fe_modal_cost', 'time span t must be positive')
        end if
        if (stat%code /= STATUS_OK) return
        n = mesh%nfree
        allocate (phi(n, n), ax(n), q(n), v(n), etadot(n))
        call fe_modes(mesh, rotary, omega, phi, ax, stat)
        if (stat%code /= STATUS_OK) return
        call fe_q_from_nodes(mesh, shape0, q, shape0_out)
        call fe_q_from_nodes(mesh, vel0, v, vel0_out)
        call fe_modal_coordinates(mesh, rotary, phi, q, eta, stat)
        if (stat%code == STATUS_OK) call fe_modal_coordinates(mesh, rotary, phi, v, etadot, stat)
        if (stat%code == STATUS_OK) call fe_modal_cost(omega, eta, etadot, t, kinetic, potential)
    end subroutine fe_modal_cost_nodes

    !> Dense system at the free vector q (for checks): strain energy, internal
    !! force NLT(q), the Newton matrix d(NLT - Q)/dq, the mass matrix (rotary
    !! inertia of Eq. 132 with rotary) and the tip load vector Q(q).
    subroutine fe_system_dense(mesh, load, rotary, q, energy, force, jac, mass, qload, stat)
        type(fe_mesh_t), intent(in) :: mesh
        type(fe_load_t), intent(in) :: load
        logical, intent(in) :: rotary
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: energy, force(:), jac(:, :), mass(:, :), qload(:)
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: r(:), band(:, :)
        energy = 0.0_dp
        force = 0.0_dp
        jac = 0.0_dp
        mass = 0.0_dp
        qload = 0.0_dp
        call check_nfree(mesh, size(q), 'api_fe_system', stat)
        if (stat%code /= STATUS_OK) return
        allocate (r(mesh%nfree), band(fe_band_rows(mesh), mesh%nfree))
        call fe_residual(mesh, load, q, r, band)
        call fe_tip_load(mesh, q, load, qload)
        force = r + qload
        call band_to_dense(band, mesh%kl, mesh%ku, jac)
        call fe_mass(mesh, q, rotary, band)
        call band_to_dense(band, mesh%kl, mesh%ku, mass)
        energy = fe_energy(mesh, q)
    end subroutine fe_system_dense
end module beamid_fe_nodes
