!> f2py binding of the nonlinear finite element chain (Chapter IV): argument
!! conversion and one call into beamid_fe_nodes each (node tables, loads and
!! options are described there).
!!
!! Plain arrays with c_int/c_double kinds and an integer status with a
!! 256-character message. The model is (nbeams, params) in the layout of
!! beamid_model, the mesh elements_per_beam (nepb); sizes that follow from
!! the arguments are hidden from Python (`!f2py intent(hide)`), nfree (which
!! depends on the compliances) comes from api_fe_mesh_sizes. Outputs of a
!! failed call are zeros: f2py allocates them zeroed.
module beamid_api_fe
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_status, only: status_t, STATUS_OK, status_out
    use beamid_fe_assembly, only: fe_mesh_t, fe_load_t
    use beamid_fe_static, only: fe_newton_opts_t
    use beamid_fe_modes, only: fe_axial_modes_linear
    use beamid_fe_nodes, only: fe_mesh_from_params, fe_load_from_values, fe_setup, &
                               fe_static_nodes, fe_path_nodes, fe_buckling_nodes, &
                               fe_modes_table, fe_modal_cost_nodes, fe_system_dense
    implicit none
    private

    public :: api_fe_static, api_fe_path, api_fe_buckling, api_fe_modes
    public :: api_fe_axial_linear, api_fe_modal_cost, api_fe_system, api_fe_mesh_sizes

contains

    !> Number of nodes, free unknowns, compliant joints (hinges) and the
    !! half-bandwidth of the mesh of the model `params`.
    subroutine api_fe_mesh_sizes(nbeams, nparams, params, nepb, nnode, nfree, nhinge, band, &
                                 code, message)
        !f2py intent(hide) nparams
        integer(c_int), intent(in) :: nbeams, nparams, nepb
        real(c_double), intent(in) :: params(nparams)
        integer(c_int), intent(out) :: nnode, nfree, nhinge, band, code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(status_t) :: stat
        call fe_mesh_from_params(nbeams, params, nepb, mesh, stat)
        nnode = mesh%nnode
        nfree = mesh%nfree
        nhinge = mesh%nhinge
        band = mesh%kl
        call status_out(stat, code, message)
    end subroutine api_fe_mesh_sizes

    !> Static equilibrium (fe_static_nodes): use_guess = 1 starts Newton at
    !! the full load from `guess` (outboard slopes `guess_out`); 0 steps the
    !! load up in nsteps initial steps (0: default).
    subroutine api_fe_static(nbeams, nparams, params, nepb, nnode, loads, use_guess, nsteps, &
                             tol, guess, guess_out, nodes, nodes_out, energy, reactions, &
                             residual, info, code, message)
        !f2py intent(hide) nparams, nnode
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
        type(status_t) :: stat
        call fe_setup(nbeams, params, nepb, loads, nsteps, tol, mesh, load, opts, stat, nnode)
        if (stat%code == STATUS_OK) then
            call fe_static_nodes(mesh, load, use_guess /= 0, opts, guess, guess_out, nodes, &
                                 nodes_out, energy, reactions, residual, info, stat)
        end if
        call status_out(stat, code, message)
    end subroutine api_fe_static

    !> Path of equilibria under load0 + lam * dload (fe_path_nodes): npts <=
    !! maxpts points lam, node tables and outboard slopes.
    subroutine api_fe_path(nbeams, nparams, params, nepb, nnode, load0, dload, guess, &
                           guess_out, lam0, ds, ds_max, direction, lam_min, lam_max, tol, &
                           maxpts, npts, lam, nodes, nodes_out, code, message)
        !f2py intent(hide) nparams, nnode
        integer(c_int), intent(in) :: nbeams, nparams, nepb, nnode, direction, maxpts
        real(c_double), intent(in) :: params(nparams), load0(4), dload(3), guess(5, nnode)
        real(c_double), intent(in) :: guess_out(2, nnode)
        real(c_double), intent(in) :: lam0, ds, ds_max, lam_min, lam_max, tol
        integer(c_int), intent(out) :: npts, code
        real(c_double), intent(out) :: lam(maxpts), nodes(5, nnode, maxpts)
        real(c_double), intent(out) :: nodes_out(2, nnode, maxpts)
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(fe_load_t) :: l0
        type(fe_newton_opts_t) :: opts
        type(status_t) :: stat
        call fe_setup(nbeams, params, nepb, load0, 0, tol, mesh, l0, opts, stat, nnode)
        if (stat%code == STATUS_OK) then
            call fe_path_nodes(mesh, l0, dload, guess, guess_out, lam0, ds, ds_max, direction, &
                               lam_min, lam_max, opts, npts, lam, nodes, nodes_out, stat)
        end if
        call status_out(stat, code, message)
    end subroutine api_fe_path

    !> Linear buckling load and mode of the straight chain (fe_buckling_nodes).
    subroutine api_fe_buckling(nbeams, nparams, params, nepb, nnode, pcr, mode, mode_out, code, &
                               message)
        !f2py intent(hide) nparams
        !f2py integer(c_int) intent(hide), depend(nbeams, nepb) :: nnode = nbeams*nepb + 1
        integer(c_int), intent(in) :: nbeams, nparams, nepb, nnode
        real(c_double), intent(in) :: params(nparams)
        real(c_double), intent(out) :: pcr, mode(5, nnode), mode_out(2, nnode)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(status_t) :: stat
        call fe_mesh_from_params(nbeams, params, nepb, mesh, stat, nnode)
        if (stat%code == STATUS_OK) call fe_buckling_nodes(mesh, pcr, mode, mode_out, stat)
        call status_out(stat, code, message)
    end subroutine api_fe_buckling

    !> Linear modes (fe_modes_table); rotary = 1 adds the rotary inertia of
    !! the end masses (Eq. 130-132).
    subroutine api_fe_modes(nbeams, nparams, params, nepb, rotary, nfree, omega, phi, axial, &
                            dofs, code, message)
        !f2py intent(hide) nparams
        integer(c_int), intent(in) :: nbeams, nparams, nepb, rotary, nfree
        real(c_double), intent(in) :: params(nparams)
        real(c_double), intent(out) :: omega(nfree), phi(nfree, nfree)
        integer(c_int), intent(out) :: axial(nfree), dofs(2, nfree), code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(status_t) :: stat
        call fe_mesh_from_params(nbeams, params, nepb, mesh, stat)
        if (stat%code == STATUS_OK) then
            call fe_modes_table(mesh, rotary /= 0, omega, phi, axial, dofs, stat)
        end if
        call status_out(stat, code, message)
    end subroutine api_fe_modes

    !> Axial frequencies of the linear-u verification model (Eq. 114, Table 7).
    subroutine api_fe_axial_linear(nbeams, nparams, params, nepb, point_masses, nel, omega, &
                                   code, message)
        !f2py intent(hide) nparams
        !f2py integer(c_int) intent(hide), depend(nbeams, nepb) :: nel = nbeams*nepb
        integer(c_int), intent(in) :: nbeams, nparams, nepb, point_masses, nel
        real(c_double), intent(in) :: params(nparams)
        real(c_double), intent(out) :: omega(nel)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(status_t) :: stat
        call fe_mesh_from_params(nbeams, params, nepb, mesh, stat, nel + 1)
        if (stat%code == STATUS_OK) call fe_axial_modes_linear(mesh, point_masses /= 0, omega, stat)
        call status_out(stat, code, message)
    end subroutine api_fe_axial_linear

    !> Skelton's modal cost (fe_modal_cost_nodes) over [0, t].
    subroutine api_fe_modal_cost(nbeams, nparams, params, nepb, rotary, nnode, nfree, shape0, &
                                 shape0_out, vel0, vel0_out, t, omega, eta, kinetic, potential, &
                                 code, message)
        !f2py intent(hide) nparams, nnode
        integer(c_int), intent(in) :: nbeams, nparams, nepb, rotary, nnode, nfree
        real(c_double), intent(in) :: params(nparams), shape0(5, nnode), vel0(5, nnode), t
        real(c_double), intent(in) :: shape0_out(2, nnode), vel0_out(2, nnode)
        real(c_double), intent(out) :: omega(nfree), eta(nfree), kinetic(nfree), potential(nfree)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(status_t) :: stat
        call fe_mesh_from_params(nbeams, params, nepb, mesh, stat, nnode)
        if (stat%code == STATUS_OK) then
            call fe_modal_cost_nodes(mesh, rotary /= 0, shape0, shape0_out, vel0, vel0_out, t, &
                                     omega, eta, kinetic, potential, stat)
        end if
        call status_out(stat, code, message)
    end subroutine api_fe_modal_cost

    !> Dense system at the free vector q (fe_system_dense, for checks).
    subroutine api_fe_system(nbeams, nparams, params, nepb, rotary, nfree, q, loads, energy, &
                             force, jac, mass, qload, code, message)
        !f2py intent(hide) nparams, nfree
        integer(c_int), intent(in) :: nbeams, nparams, nepb, rotary, nfree
        real(c_double), intent(in) :: params(nparams), q(nfree), loads(4)
        real(c_double), intent(out) :: energy, force(nfree), jac(nfree, nfree)
        real(c_double), intent(out) :: mass(nfree, nfree), qload(nfree)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(fe_mesh_t) :: mesh
        type(fe_load_t) :: load
        type(status_t) :: stat
        call fe_mesh_from_params(nbeams, params, nepb, mesh, stat)
        if (stat%code == STATUS_OK) call fe_load_from_values(loads, load, stat)
        if (stat%code == STATUS_OK) then
            call fe_system_dense(mesh, load, rotary /= 0, q, energy, force, jac, mass, qload, &
                                 stat)
        end if
        call status_out(stat, code, message)
    end subroutine api_fe_system
end module beamid_api_fe
