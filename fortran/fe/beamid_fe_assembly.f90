!> Banded global assembly of the nonlinear finite element chain (Chapter IV).
!!
!! The chain of `nbeams` beams is cut into elements; neighbouring elements share
!! a node, and a node carries four unknowns in the order of Eq. 83:
!! [w, w', u, u'] (full indices 4(node-1) + 1..4). A rigid joint is locked:
!! w, w', u, u' are continuous across it, as in the dissertation. A compliant
!! joint k (joint_flex(k) = f > 0) is a hinge with a rotational spring: its
!! node keeps one position (u, w) but carries a second slope pair (w'+, u'+)
!! for the outboard beam (full indices 4 nnode + 2(j-1) + 1..2 for hinge j),
!! and the spring energy (psi+ - psi-)^2 / (2 f) with psi = atan2(w', 1 + u')
!! (docs/theory_fe.md, Section 8). Point masses sit on the joint and tip
!! nodes. The clamped root fixes w, w' and u of node 1 (Eq. 103); with
!! root_flex > 0 it fixes w and u only and a spring psi(0)^2 / (2 root_flex)
!! holds the root slope. The remaining unknowns are the "free" vector q of
!! length nfree, numbered node by node ([w, w', u, u'], or at a hinge
!! [w'-, u'-, w, u, w'+, u'+]), so an element touches 8 consecutive free
!! unknowns and every matrix has half-bandwidth 7 (computed from the mesh:
!! mesh%kl, mesh%ku). With all compliances zero the numbering, and every
!! number, is that of the rigid chain.
!!
!! Eliminating the three clamped unknowns is the Lagrange-multiplier projection
!! of Eq. 104-107 (see docs/theory_fe.md): with C = [I 0], the projector
!! I - C^T (C M^-1 C^T)^-1 C M^-1 removes exactly the constrained rows, and the
!! multipliers are the root reactions lambda = (NLT - Q) restricted to them.
!!
!! Matrices are returned in LAPACK general band storage with 2*kl+ku+1 rows
!! (row kl+ku+1+i-j holds A(i,j)), ready for beamid_lapack's solve_banded.
!! Every routine costs O(number of elements).
module beamid_fe_assembly
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, ERR_INPUT, ERR_SIZE, MAX_BYTES, fmt_int, &
                             fmt_real, fmt_bytes, fmt_count, set_alloc_error
    use beamid_model, only: chain_t
    use beamid_fe_element, only: FE_NDOF, fe_gauss_points, fe_quadrature_order, &
                                 fe_gauss_table, fe_element_energy, &
                                 fe_element_force_tabulated, fe_element_tangent_tabulated, &
                                 fe_element_mass, fe_hinge_energy, fe_hinge_force, &
                                 fe_hinge_tangent, fe_element_tangent_dir, &
                                 fe_hinge_tangent_dir, fe_angle_hessian_dir
    ! the band helpers live in beamid_band; the fe_band_* names stay exported
    ! from here for the callers that import them with the mesh
    use beamid_band, only: band_add, band_scatter, fe_band_add => band_add, &
                           fe_band_to_dense => band_to_dense, fe_band_matvec => band_mv
    implicit none
    private

    public :: fe_mesh_t, fe_load_t, fe_mesh_build
    public :: fe_band_rows, fe_band_add, fe_band_to_dense, fe_band_matvec
    public :: fe_work_t, fe_work_init, fe_residual, fe_check_dense
    public :: fe_internal_force, fe_tangent, fe_energy, fe_mass, fe_stiffness_linear
    public :: fe_tip_load, fe_tip_load_jacobian, fe_reactions
    public :: fe_wire_tip, fe_wire_force, fe_wire_jacobian
    public :: fe_tangent_dir, fe_mass_dir, fe_tip_load_jacobian_dir, fe_wire_jacobian_dir
    public :: fe_expand, fe_node_value, fe_spring_dofs
    public :: FE_BAND, DOF_W, DOF_DW, DOF_U, DOF_DU, DOF_DW_OUT, DOF_DU_OUT
    public :: FE_MOMENT_EQ78, FE_MOMENT_EXACT

    !> Half-bandwidth of the rigid chain (8 unknowns per element); a mesh's
    !! own is mesh%kl, mesh%ku.
    integer, parameter :: FE_BAND = FE_NDOF - 1
    !> Components of a node, in the order of Eq. 83, and the outboard slopes
    !! of a hinged joint (equal to DOF_DW, DOF_DU entries at other nodes).
    integer, parameter :: DOF_W = 1, DOF_DW = 2, DOF_U = 3, DOF_DU = 4
    integer, parameter :: DOF_DW_OUT = 5, DOF_DU_OUT = 6
    !> Tip moment virtual work: Eq. 78 as printed (M [(1+u') dw' - w' du'], the
    !! small-strain form of delta Psi) or the exact delta Psi of Eq. 73.
    integer, parameter :: FE_MOMENT_EQ78 = 0, FE_MOMENT_EXACT = 1

    !> The discretized chain. Element arrays are indexed 1..nel, node arrays
    !! 1..nnode (node 1 is the clamped root, node nnode the tip).
    type :: fe_mesh_t
        integer :: nbeams = 0
        integer :: nel = 0         !< number of elements
        integer :: nnode = 0       !< nel + 1
        integer :: ndof = 0        !< 4 * nnode + 2 * nhinge, all unknowns
        integer :: nfree = 0       !< unknowns left after the clamp (ndof - 3, or - 2)
        integer :: kl = FE_BAND    !< sub-diagonals (from the numbering)
        integer :: ku = FE_BAND    !< super-diagonals (from the numbering)
        integer :: nhinge = 0      !< compliant joints (joint_flex > 0)
        real(dp) :: root_flex = 0.0_dp           !< root hinge compliance (0: clamp)
        integer, allocatable :: hinge_node(:)    !< node of each compliant joint
        real(dp), allocatable :: hinge_flex(:)   !< its compliance f (rad per N m)
        !> Full index of component 1..6 (DOF_W..DOF_DU_OUT) of each node,
        !! (6, nnode); rows 5-6 repeat rows 2 and 4 except at a hinge.
        integer, allocatable :: node_dof(:, :)
        !> Full indices of the 8 unknowns of each element, (FE_NDOF, nel):
        !! the outboard slopes of its first node, the inboard of its second.
        integer, allocatable :: el_dof(:, :)
        integer, allocatable :: free_comp(:)    !< component (1..6) of each free unknown
        integer, allocatable :: free_node(:)    !< node of each free unknown
        real(dp), allocatable :: h(:), ea(:), ei(:), rho(:), cubic(:)
        integer, allocatable :: beam(:)         !< beam of each element
        real(dp), allocatable :: s(:)           !< undeformed arc length of each node
        real(dp), allocatable :: node_mass(:)   !< point mass at each node (kg)
        real(dp), allocatable :: node_inertia(:) !< point rotary inertia (kg m^2)
        integer, allocatable :: free_of(:)      !< full unknown -> free index (0: clamped)
        integer, allocatable :: full_of(:)      !< free index -> full unknown
        real(dp), allocatable :: xg(:), wg(:)   !< Gauss rule on [0, 1]
        !> Free index of each element unknown, free_of(el_dof), (FE_NDOF, nel);
        !! 0 for a clamped unknown.
        integer, allocatable :: el_free(:, :)
        !> First free index of each element whose 8 unknowns are all free and
        !! numbered consecutively (every element away from the clamp and the
        !! hinges), else 0.
        integer, allocatable :: el_first_free(:)
        !> Hermite derivatives df/ds, d2f/ds2 (Eq. 76) at the Gauss points of
        !! the elements of each beam, (4, size(xg), nbeams), and the weights
        !! wg h, (size(xg), nbeams), from fe_gauss_table: the elements of a beam
        !! share their length h, so the tables are made once per mesh.
        real(dp), allocatable :: gauss_d1(:, :, :), gauss_d2(:, :, :), gauss_wh(:, :)
    end type fe_mesh_t

    !> Loads at the tip: a force of fixed direction (fx along the undeformed
    !! axis, fy across it) and a moment (Eq. 78).
    type :: fe_load_t
        real(dp) :: fx = 0.0_dp
        real(dp) :: fy = 0.0_dp
        real(dp) :: moment = 0.0_dp
        integer :: moment_form = FE_MOMENT_EQ78
    end type fe_load_t

    !> Work arrays of the force, tangent and residual routines (BeamDyn's
    !! MiscVar): made once per mesh by fe_work_init and handed to every call of
    !! a solve or a run, instead of arrays made on each call. Without one, a
    !! call makes its own.
    type :: fe_work_t
        real(dp), allocatable :: qpad(:), fpad(:)   !< (0:nfree): [0, q] and the force
        real(dp), allocatable :: qv(:)              !< tip load vector Q(q)
        real(dp), allocatable :: kb(:, :)           !< tangent of a residual-only call
    end type fe_work_t

contains

    !> Work arrays for the force, tangent and residual calls on `mesh`.
    pure subroutine fe_work_init(mesh, work)
        type(fe_mesh_t), intent(in) :: mesh
        type(fe_work_t), intent(out) :: work
        allocate (work%qpad(0:mesh%nfree), work%fpad(0:mesh%nfree), work%qv(mesh%nfree), &
                  work%kb(fe_band_rows(mesh), mesh%nfree))
    end subroutine fe_work_init

    !> ERR_SIZE, naming `where`, when a dense eigenproblem of order n (three
    !! n x n matrices) would need more memory than MAX_BYTES.
    pure subroutine fe_check_dense(n, where, stat)
        integer, intent(in) :: n
        character(len=*), intent(in) :: where
        type(status_t), intent(inout) :: stat
        real(dp) :: bytes
        bytes = 8.0_dp*3.0_dp*real(n, dp)**2
        if (bytes > MAX_BYTES) call set_status(stat, ERR_SIZE, where, &
            'the dense eigenproblem of '//fmt_int(n)//' unknowns would need about '// &
            fmt_bytes(bytes)//' of memory (limit '//fmt_bytes(MAX_BYTES)//'): use fewer elements')
    end subroutine fe_check_dense

    !> Discretize `chain` with `elements_per_beam` equal elements on each beam.
    !! A joint with joint_flex > 0 becomes a hinge with a rotational spring, a
    !! root_flex > 0 a hinge spring at the clamp; zero compliances give the
    !! dissertation's locked elbow and clamp, with the rigid numbering.
    pure subroutine fe_mesh_build(chain, elements_per_beam, mesh, stat)
        type(chain_t), intent(in) :: chain
        integer, intent(in) :: elements_per_beam
        type(fe_mesh_t), intent(out) :: mesh
        type(status_t), intent(inout) :: stat
        type(status_t) :: st
        real(dp) :: bytes
        call check_mesh_request(chain, elements_per_beam, bytes, st)
        if (st%code == 0) call mesh_elements(chain, elements_per_beam, bytes, mesh, st)
        if (st%code == 0) call mesh_numbering(chain, elements_per_beam, bytes, mesh, st)
        if (st%code == 0) call mesh_free_numbering(bytes, mesh, st)
        if (st%code == 0) then
            mesh%kl = half_bandwidth(mesh)
            mesh%ku = mesh%kl
            call mesh_assembly_tables(elements_per_beam, bytes, mesh, st)
        end if
        if (st%code /= 0) stat = st
    end subroutine fe_mesh_build

    !> The checks of fe_mesh_build before anything is allocated; bytes: the
    !! memory the mesh's solvers need (in 64 bits: about 40 numbers per
    !! unknown, 4 unknowns per node), held against MAX_BYTES.
    pure subroutine check_mesh_request(chain, elements_per_beam, bytes, stat)
        type(chain_t), intent(in) :: chain
        integer, intent(in) :: elements_per_beam
        real(dp), intent(out) :: bytes
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'fe_mesh_build'
        integer :: i, nb
        nb = chain%nbeams
        bytes = 8.0_dp*40.0_dp*4.0_dp*(real(nb, dp)*real(elements_per_beam, dp) + 1.0_dp)
        if (elements_per_beam < 1) then
            call set_status(stat, ERR_INPUT, where, 'elements_per_beam = '// &
                            fmt_int(elements_per_beam)//', expected at least 1')
            return
        end if
        if (nb < 1) then
            call set_status(stat, ERR_INPUT, where, 'the chain has no beams')
            return
        end if
        if (.not. (chain%root_flex >= 0.0_dp .and. chain%root_flex <= huge(1.0_dp))) then
            call set_status(stat, ERR_INPUT, where, 'root_flex = '// &
                            fmt_real(chain%root_flex)//', expected a finite number >= 0')
            return
        end if
        do i = 1, nb - 1
            if (.not. (chain%joint_flex(i) >= 0.0_dp .and. &
                       chain%joint_flex(i) <= huge(1.0_dp))) then
                call set_status(stat, ERR_INPUT, where, 'joint '//fmt_int(i)// &
                                ' flex = '//fmt_real(chain%joint_flex(i))// &
                                ', expected a finite number >= 0')
                return
            end if
        end do
        if (bytes > MAX_BYTES) then
            call set_status(stat, ERR_SIZE, where, 'elements_per_beam = '// &
                            fmt_int(elements_per_beam)//': a mesh of '// &
                            fmt_count(real(nb, dp)*real(elements_per_beam, dp))// &
                            ' elements would need about '//fmt_bytes(bytes)// &
                            ' of memory (limit '//fmt_bytes(MAX_BYTES)//')')
        end if
    end subroutine check_mesh_request

    !> Sizes, element properties, node positions s and the point masses and
    !! inertias at the joints and the tip.
    pure subroutine mesh_elements(chain, elements_per_beam, bytes, mesh, stat)
        type(chain_t), intent(in) :: chain
        integer, intent(in) :: elements_per_beam
        real(dp), intent(in) :: bytes
        type(fe_mesh_t), intent(inout) :: mesh
        type(status_t), intent(inout) :: stat
        integer :: ib, k, el, nb, ierr
        nb = chain%nbeams
        mesh%nbeams = nb
        mesh%nel = nb*elements_per_beam
        mesh%nnode = mesh%nel + 1
        mesh%nhinge = count(chain%joint_flex(1:nb - 1) > 0.0_dp)
        mesh%root_flex = chain%root_flex
        mesh%ndof = 4*mesh%nnode + 2*mesh%nhinge
        mesh%nfree = mesh%ndof - 3
        if (mesh%root_flex > 0.0_dp) mesh%nfree = mesh%ndof - 2
        allocate (mesh%h(mesh%nel), mesh%ea(mesh%nel), mesh%ei(mesh%nel), &
                  mesh%rho(mesh%nel), mesh%cubic(mesh%nel), mesh%beam(mesh%nel), &
                  mesh%s(mesh%nnode), mesh%node_mass(mesh%nnode), &
                  mesh%node_inertia(mesh%nnode), stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(stat, 'fe_mesh_build', 'the element and node tables', bytes)
            return
        end if
        mesh%node_mass = 0.0_dp
        mesh%node_inertia = 0.0_dp
        mesh%s(1) = 0.0_dp
        el = 0
        do ib = 1, nb
            do k = 1, elements_per_beam
                el = el + 1
                mesh%beam(el) = ib
                mesh%h(el) = chain%length(ib)/real(elements_per_beam, dp)
                mesh%ea(el) = chain%ea(ib)
                mesh%ei(el) = chain%ei(ib)
                mesh%rho(el) = chain%rho(ib)
                mesh%cubic(el) = chain%cubic(ib)
                if (k == elements_per_beam) then
                    ! exact end of the beam, free of rounding from the sum of h
                    mesh%s(el + 1) = sum(chain%length(1:ib))
                else
                    mesh%s(el + 1) = mesh%s(el) + mesh%h(el)
                end if
            end do
            ! mass point ib sits at the end of beam ib (joint ib, or the tip)
            mesh%node_mass(el + 1) = chain%mass(ib)
            mesh%node_inertia(el + 1) = chain%inertia(ib)
        end do
    end subroutine mesh_elements

    !> Full indices of the node and element unknowns; a hinge's outboard
    !! slopes come after the 4 nnode node unknowns.
    pure subroutine mesh_numbering(chain, elements_per_beam, bytes, mesh, stat)
        type(chain_t), intent(in) :: chain
        integer, intent(in) :: elements_per_beam
        real(dp), intent(in) :: bytes
        type(fe_mesh_t), intent(inout) :: mesh
        type(status_t), intent(inout) :: stat
        integer :: i, j, node, el, ierr
        allocate (mesh%node_dof(6, mesh%nnode), mesh%hinge_node(mesh%nhinge), &
                  mesh%hinge_flex(mesh%nhinge), mesh%el_dof(FE_NDOF, mesh%nel), stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(stat, 'fe_mesh_build', 'the node numbering', bytes)
            return
        end if
        do node = 1, mesh%nnode
            mesh%node_dof(1:4, node) = 4*(node - 1) + [1, 2, 3, 4]
            mesh%node_dof(5:6, node) = mesh%node_dof([DOF_DW, DOF_DU], node)
        end do
        j = 0
        do i = 1, mesh%nbeams - 1
            if (chain%joint_flex(i) > 0.0_dp) then
                j = j + 1
                node = i*elements_per_beam + 1
                mesh%hinge_node(j) = node
                mesh%hinge_flex(j) = chain%joint_flex(i)
                mesh%node_dof(5:6, node) = 4*mesh%nnode + 2*(j - 1) + [1, 2]
            end if
        end do
        do el = 1, mesh%nel
            mesh%el_dof(:, el) = [mesh%node_dof([DOF_W, DOF_DW_OUT, DOF_U, DOF_DU_OUT], el), &
                                  mesh%node_dof(1:4, el + 1)]
        end do
    end subroutine mesh_numbering

    !> The free numbering, node by node; the clamp of Eq. 103 fixes w, w', u
    !! of the root (w and u only with a root hinge); u' (the root strain)
    !! stays free.
    pure subroutine mesh_free_numbering(bytes, mesh, stat)
        real(dp), intent(in) :: bytes
        type(fe_mesh_t), intent(inout) :: mesh
        type(status_t), intent(inout) :: stat
        integer :: node, i, k, kf, r, full, order(6), ierr
        allocate (mesh%free_of(mesh%ndof), mesh%full_of(mesh%nfree), &
                  mesh%free_comp(mesh%nfree), mesh%free_node(mesh%nfree), stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(stat, 'fe_mesh_build', 'the free numbering', bytes)
            return
        end if
        mesh%free_of = 0
        kf = 0
        do node = 1, mesh%nnode
            if (any(mesh%hinge_node == node)) then
                order = [DOF_DW, DOF_DU, DOF_W, DOF_U, DOF_DW_OUT, DOF_DU_OUT]
                k = 6
            else
                order(1:4) = [DOF_W, DOF_DW, DOF_U, DOF_DU]
                k = 4
            end if
            do i = 1, k
                r = order(i)
                if (node == 1 .and. (r == DOF_W .or. r == DOF_U)) cycle
                if (node == 1 .and. r == DOF_DW .and. .not. mesh%root_flex > 0.0_dp) cycle
                full = mesh%node_dof(r, node)
                kf = kf + 1
                mesh%free_of(full) = kf
                mesh%full_of(kf) = full
                mesh%free_comp(kf) = r
                mesh%free_node(kf) = node
            end do
        end do
    end subroutine mesh_free_numbering

    !> Half-bandwidth: the widest coupling of an element or a hinge spring.
    pure integer function half_bandwidth(mesh) result(span)
        type(fe_mesh_t), intent(in) :: mesh
        integer, allocatable :: idx(:)
        integer :: el, j
        span = 0
        do el = 1, mesh%nel
            idx = pack(mesh%free_of(mesh%el_dof(:, el)), mesh%free_of(mesh%el_dof(:, el)) > 0)
            span = max(span, maxval(idx) - minval(idx))
        end do
        do j = 1, mesh%nhinge
            idx = mesh%free_of(mesh%node_dof([DOF_DW, DOF_DU, DOF_DW_OUT, DOF_DU_OUT], &
                                             mesh%hinge_node(j)))
            span = max(span, maxval(idx) - minval(idx))
        end do
    end function half_bandwidth

    !> The quadrature and the tables of the assembly loops (fe_internal_force,
    !! fe_tangent): free indices per element, the first of 8 consecutive ones,
    !! and the Hermite derivatives at the Gauss points of each beam.
    pure subroutine mesh_assembly_tables(elements_per_beam, bytes, mesh, stat)
        integer, intent(in) :: elements_per_beam
        real(dp), intent(in) :: bytes
        type(fe_mesh_t), intent(inout) :: mesh
        type(status_t), intent(inout) :: stat
        integer :: k, el, ib, i, kf, ierr
        k = fe_quadrature_order(maxval(abs(mesh%cubic)))
        allocate (mesh%xg(k), mesh%wg(k))
        call fe_gauss_points(k, mesh%xg, mesh%wg)
        allocate (mesh%el_free(FE_NDOF, mesh%nel), mesh%el_first_free(mesh%nel), stat=ierr)
        if (ierr /= 0) then
            call set_alloc_error(stat, 'fe_mesh_build', 'the assembly tables', bytes)
            return
        end if
        do el = 1, mesh%nel
            mesh%el_free(:, el) = mesh%free_of(mesh%el_dof(:, el))
            kf = mesh%el_free(1, el)
            mesh%el_first_free(el) = kf
            do i = 2, FE_NDOF
                if (kf == 0 .or. mesh%el_free(i, el) /= kf + i - 1) mesh%el_first_free(el) = 0
            end do
        end do
        allocate (mesh%gauss_d1(4, k, mesh%nbeams), mesh%gauss_d2(4, k, mesh%nbeams), &
                  mesh%gauss_wh(k, mesh%nbeams))
        do ib = 1, mesh%nbeams
            el = (ib - 1)*elements_per_beam + 1   ! first element of beam ib
            call fe_gauss_table(mesh%h(el), mesh%xg, mesh%wg, mesh%gauss_d1(:, :, ib), &
                                mesh%gauss_d2(:, :, ib), mesh%gauss_wh(:, ib))
        end do
    end subroutine mesh_assembly_tables

    !> Rows of the band storage (2 kl + ku + 1).
    pure integer function fe_band_rows(mesh)
        type(fe_mesh_t), intent(in) :: mesh
        fe_band_rows = 2*mesh%kl + mesh%ku + 1
    end function fe_band_rows

    !> Full unknown vector (clamped entries zero) from the free vector q.
    pure subroutine fe_expand(mesh, q, qfull)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: qfull(:)
        qfull = 0.0_dp
        qfull(mesh%full_of) = q
    end subroutine fe_expand

    !> Value of component `comp` (DOF_W..DOF_DU_OUT) at node `node` from free
    !! q. DOF_DW_OUT, DOF_DU_OUT are the slopes of the outboard element at the
    !! node: the second slope pair at a hinge, the node's w', u' elsewhere.
    pure real(dp) function fe_node_value(mesh, q, node, comp)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        integer, intent(in) :: node, comp
        integer :: k
        k = mesh%free_of(mesh%node_dof(comp, node))
        if (k == 0) then
            fe_node_value = 0.0_dp
        else
            fe_node_value = q(k)
        end if
    end function fe_node_value

    !> The free vector q with a zero in front, qpad(0:nfree) = [0, q]:
    !! indexed with mesh%el_free or a spring's free indices it gives every
    !! unknown an element or spring touches, 0 for a clamped one, without a
    !! full-length copy. Forces are gathered the same way into a padded vector
    !! whose entry 0 (the clamped rows) is dropped.
    pure subroutine pad_free(q, qpad)
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: qpad(0:)
        qpad(0) = 0.0_dp
        qpad(1:) = q
    end subroutine pad_free

    !> Element unknowns of element `el` from the padded free vector.
    pure subroutine element_vector(mesh, qpad, el, qe)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: qpad(0:)
        integer, intent(in) :: el
        real(dp), intent(out) :: qe(FE_NDOF)
        integer :: a
        do a = 1, FE_NDOF
            qe(a) = qpad(mesh%el_free(a, el))
        end do
    end subroutine element_vector

    !> Free indices of the slopes a spring acts on, [w'-, u'-, w'+, u'+]
    !! (0 for a clamped one): spring 0 is the root hinge (its inboard side is
    !! the clamp), spring j >= 1 the hinge at mesh%hinge_node(j).
    pure subroutine fe_spring_dofs(mesh, j, idx, flex)
        type(fe_mesh_t), intent(in) :: mesh
        integer, intent(in) :: j
        integer, intent(out) :: idx(4)
        real(dp), intent(out) :: flex
        if (j == 0) then
            idx = [0, 0, mesh%free_of(mesh%node_dof(DOF_DW, 1)), &
                   mesh%free_of(mesh%node_dof(DOF_DU, 1))]
            flex = mesh%root_flex
        else
            idx = mesh%free_of(mesh%node_dof([DOF_DW, DOF_DU, DOF_DW_OUT, DOF_DU_OUT], &
                                             mesh%hinge_node(j)))
            flex = mesh%hinge_flex(j)
        end if
    end subroutine fe_spring_dofs

    !> Energy of the joint and root springs at the padded free vector qpad.
    pure real(dp) function spring_energy(mesh, qpad) result(v)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: qpad(0:)
        integer :: j, idx(4)
        real(dp) :: flex
        v = 0.0_dp
        do j = merge(0, 1, mesh%root_flex > 0.0_dp), mesh%nhinge
            call fe_spring_dofs(mesh, j, idx, flex)
            v = v + fe_hinge_energy(flex, qpad(idx))
        end do
    end function spring_energy

    !> fpad += spring forces and, if present, kb += spring tangents, on the
    !! padded free vectors (entry 0 collects the clamped rows).
    pure subroutine add_springs(mesh, qpad, fpad, kb)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: qpad(0:)
        real(dp), intent(inout) :: fpad(0:)
        real(dp), intent(inout), optional :: kb(:, :)
        integer :: j, a, idx(4)
        real(dp) :: flex, fs(4), ks(4, 4)
        do j = merge(0, 1, mesh%root_flex > 0.0_dp), mesh%nhinge
            call fe_spring_dofs(mesh, j, idx, flex)
            if (present(kb)) then
                call fe_hinge_tangent(flex, qpad(idx), fs, ks)
            else
                call fe_hinge_force(flex, qpad(idx), fs)
            end if
            do a = 1, 4
                fpad(idx(a)) = fpad(idx(a)) + fs(a)
            end do
            if (present(kb)) call band_scatter(kb, mesh%kl, mesh%ku, idx, ks)
        end do
    end subroutine add_springs

    !> Strain energy V of the chain (Eq. 87) at the free vector q, with the
    !! energy of the hinge springs.
    pure real(dp) function fe_energy(mesh, q) result(v)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        real(dp) :: qpad(0:mesh%nfree), qe(FE_NDOF)
        integer :: el
        call pad_free(q, qpad)
        v = 0.0_dp
        do el = 1, mesh%nel
            call element_vector(mesh, qpad, el, qe)
            v = v + fe_element_energy(mesh%h(el), mesh%ea(el), mesh%ei(el), mesh%cubic(el), &
                                      mesh%xg, mesh%wg, qe)
        end do
        v = v + spring_energy(mesh, qpad)
    end function fe_energy

    !> Internal force NLT(q) = dV/dq on the free unknowns (Eq. 79-83).
    pure subroutine fe_internal_force(mesh, q, f, work)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: f(:)
        type(fe_work_t), intent(inout), optional :: work
        if (present(work)) then
            call internal_force(mesh, q, f, work%qpad, work%fpad)
        else
            block
                real(dp) :: qpad(0:mesh%nfree), fpad(0:mesh%nfree)
                call internal_force(mesh, q, f, qpad, fpad)
            end block
        end if
    end subroutine fe_internal_force

    !> fe_internal_force on the padded work vectors qpad, fpad (0:nfree).
    pure subroutine internal_force(mesh, q, f, qpad, fpad)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: f(:), qpad(0:), fpad(0:)
        real(dp) :: qe(FE_NDOF), fe(FE_NDOF)
        integer :: el, ib, a
        call pad_free(q, qpad)
        fpad = 0.0_dp
        do el = 1, mesh%nel
            ib = mesh%beam(el)
            call element_vector(mesh, qpad, el, qe)
            call fe_element_force_tabulated(size(mesh%xg), mesh%gauss_d1(:, :, ib), &
                                            mesh%gauss_d2(:, :, ib), mesh%gauss_wh(:, ib), &
                                            mesh%ea(el), mesh%ei(el), mesh%cubic(el), qe, fe)
            do a = 1, FE_NDOF
                fpad(mesh%el_free(a, el)) = fpad(mesh%el_free(a, el)) + fe(a)
            end do
        end do
        call add_springs(mesh, qpad, fpad)
        f = fpad(1:)
    end subroutine internal_force

    !> Root reactions: the Lagrange multipliers of Eq. 104-105 for a static
    !! state, lambda = NLT(q) on the clamped unknowns (w, w', u of node 1);
    !! tip loads never act on the clamped unknowns directly. For a dynamic
    !! state the caller adds the inertia force on those rows. With a root
    !! hinge, reactions(2) is the first element's force on the w' row: in
    !! equilibrium minus the root spring's, i.e. the moment it transmits.
    pure subroutine fe_reactions(mesh, q, reactions)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: reactions(3)
        real(dp) :: qpad(0:mesh%nfree), qe(FE_NDOF), fe(FE_NDOF)
        call pad_free(q, qpad)
        call element_vector(mesh, qpad, 1, qe)
        call fe_element_force_tabulated(size(mesh%xg), mesh%gauss_d1(:, :, 1), &
                                        mesh%gauss_d2(:, :, 1), mesh%gauss_wh(:, 1), &
                                        mesh%ea(1), mesh%ei(1), mesh%cubic(1), qe, fe)
        reactions = fe(1:3)
    end subroutine fe_reactions

    !> Internal force f and tangent stiffness K_T = dNLT/dq (band storage,
    !! fe_band_rows(mesh) x nfree) at the free vector q; without f the
    !! stiffness alone (the element kernels skip the force).
    pure subroutine fe_tangent(mesh, q, f, kb, work)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        real(dp), intent(out), optional :: f(:)
        real(dp), intent(out) :: kb(:, :)
        type(fe_work_t), intent(inout), optional :: work
        if (present(work)) then
            call tangent(mesh, q, kb, work%qpad, work%fpad, f)
        else
            block
                real(dp) :: qpad(0:mesh%nfree), fpad(0:mesh%nfree)
                call tangent(mesh, q, kb, qpad, fpad, f)
            end block
        end if
    end subroutine fe_tangent

    !> fe_tangent on the padded work vectors qpad, fpad (0:nfree).
    pure subroutine tangent(mesh, q, kb, qpad, fpad, f)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: kb(:, :), qpad(0:), fpad(0:)
        real(dp), intent(out), optional :: f(:)
        real(dp) :: qe(FE_NDOF), fe(FE_NDOF), ke(FE_NDOF, FE_NDOF)
        integer :: el, ib, b, j, diag, first, row
        call pad_free(q, qpad)
        fpad = 0.0_dp
        kb = 0.0_dp
        ! row of the diagonal in band storage: A(i, j) is kb(diag + i - j, j)
        diag = mesh%kl + mesh%ku + 1
        do el = 1, mesh%nel
            ib = mesh%beam(el)
            call element_vector(mesh, qpad, el, qe)
            if (present(f)) then
                call fe_element_tangent_tabulated(size(mesh%xg), mesh%gauss_d1(:, :, ib), &
                                                  mesh%gauss_d2(:, :, ib), &
                                                  mesh%gauss_wh(:, ib), mesh%ea(el), &
                                                  mesh%ei(el), mesh%cubic(el), qe, ke, fe)
            else
                call fe_element_tangent_tabulated(size(mesh%xg), mesh%gauss_d1(:, :, ib), &
                                                  mesh%gauss_d2(:, :, ib), &
                                                  mesh%gauss_wh(:, ib), mesh%ea(el), &
                                                  mesh%ei(el), mesh%cubic(el), qe, ke)
            end if
            first = mesh%el_first_free(el)
            if (first > 0) then
                ! free unknowns first..first+7: column first+b-1 of A receives
                ! ke(:, b) in the consecutive band rows diag+1-b .. diag+8-b
                if (present(f)) fpad(first:first + FE_NDOF - 1) = &
                    fpad(first:first + FE_NDOF - 1) + fe
                do b = 1, FE_NDOF
                    row = diag + 1 - b
                    j = first + b - 1
                    kb(row:row + FE_NDOF - 1, j) = kb(row:row + FE_NDOF - 1, j) + ke(:, b)
                end do
                cycle
            end if
            if (present(f)) then
                do b = 1, FE_NDOF
                    fpad(mesh%el_free(b, el)) = fpad(mesh%el_free(b, el)) + fe(b)
                end do
            end if
            call band_scatter(kb, mesh%kl, mesh%ku, mesh%el_free(:, el), ke)
        end do
        call add_springs(mesh, qpad, fpad, kb)
        if (present(f)) f = fpad(1:)
    end subroutine tangent

    !> Out-of-balance force b(q) = NLT(q) - Q(q) of Eq. 84 and, optionally, its
    !! Jacobian db/dq in band storage (Eq. 85).
    pure subroutine fe_residual(mesh, load, q, r, jb, work)
        type(fe_mesh_t), intent(in) :: mesh
        type(fe_load_t), intent(in) :: load
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: r(:)
        real(dp), intent(out), optional :: jb(:, :)
        type(fe_work_t), intent(inout), optional :: work
        type(fe_work_t) :: own
        if (present(work)) then
            call residual(mesh, load, q, r, work, jb)
        else
            allocate (own%qpad(0:mesh%nfree), own%fpad(0:mesh%nfree), own%qv(mesh%nfree))
            if (.not. present(jb)) allocate (own%kb(fe_band_rows(mesh), mesh%nfree))
            call residual(mesh, load, q, r, own, jb)
        end if
    end subroutine fe_residual

    pure subroutine residual(mesh, load, q, r, work, jb)
        type(fe_mesh_t), intent(in) :: mesh
        type(fe_load_t), intent(in) :: load
        real(dp), intent(in) :: q(:)
        real(dp), intent(out) :: r(:)
        type(fe_work_t), intent(inout) :: work
        real(dp), intent(out), optional :: jb(:, :)
        if (present(jb)) then
            call tangent(mesh, q, jb, work%qpad, work%fpad, r)
            call fe_tip_load_jacobian(mesh, q, load, -1.0_dp, jb)
        else
            call tangent(mesh, q, work%kb, work%qpad, work%fpad, r)
        end if
        call fe_tip_load(mesh, q, load, work%qv)
        r = r - work%qv
    end subroutine residual

    !> Linear stiffness K = K_T(0) in band storage (Eq. 123-124).
    pure subroutine fe_stiffness_linear(mesh, kb)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(out) :: kb(:, :)
        real(dp), allocatable :: q(:), f(:)
        allocate (q(mesh%nfree), f(mesh%nfree), source=0.0_dp)
        call fe_tangent(mesh, q, f, kb)
    end subroutine fe_stiffness_linear

    !> Mass matrix in band storage: consistent element masses (Eq. 92-97) plus
    !! the point masses on u and w of the joint and tip nodes. With `rotary`,
    !! the rotary inertia J of the point masses enters through the matrix of
    !! Eq. 132 on (w', u'), evaluated at q: J [(1+u')^2, -w'(1+u'); -w'(1+u'), w'^2].
    !! At a hinge the joint mass turns with the inboard beam end (w'-, u'-).
    pure subroutine fe_mass(mesh, q, rotary, mb)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        logical, intent(in) :: rotary
        real(dp), intent(out) :: mb(:, :)
        real(dp) :: me(FE_NDOF, FE_NDOF), du, dw, jm
        integer :: el, i, node, iw, iu
        mb = 0.0_dp
        do el = 1, mesh%nel
            call fe_element_mass(mesh%h(el), mesh%rho(el), me)
            call band_scatter(mb, mesh%kl, mesh%ku, mesh%el_free(:, el), me)
        end do
        do node = 2, mesh%nnode
            if (mesh%node_mass(node) /= 0.0_dp) then
                i = mesh%free_of(4*(node - 1) + DOF_W)
                call band_add(mb, mesh%kl, mesh%ku, i, i, mesh%node_mass(node))
                i = mesh%free_of(4*(node - 1) + DOF_U)
                call band_add(mb, mesh%kl, mesh%ku, i, i, mesh%node_mass(node))
            end if
            if (rotary .and. mesh%node_inertia(node) /= 0.0_dp) then
                jm = mesh%node_inertia(node)
                iw = mesh%free_of(4*(node - 1) + DOF_DW)
                iu = mesh%free_of(4*(node - 1) + DOF_DU)
                du = q(iu)
                dw = q(iw)
                call band_add(mb, mesh%kl, mesh%ku, iw, iw, jm*(1.0_dp + du)**2)
                call band_add(mb, mesh%kl, mesh%ku, iw, iu, -jm*dw*(1.0_dp + du))
                call band_add(mb, mesh%kl, mesh%ku, iu, iw, -jm*dw*(1.0_dp + du))
                call band_add(mb, mesh%kl, mesh%ku, iu, iu, jm*dw*dw)
            end if
        end do
    end subroutine fe_mass

    !> Generalized tip load Q(q) on the free unknowns (Eq. 78): the force
    !! components on u and w of the tip node, the moment on w' and u'.
    pure subroutine fe_tip_load(mesh, q, load, qv)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        type(fe_load_t), intent(in) :: load
        real(dp), intent(out) :: qv(:)
        real(dp) :: du, dw, r2
        integer :: iw, iu, idw, idu
        call tip_indices(mesh, iw, idw, iu, idu)
        qv = 0.0_dp
        qv(iw) = load%fy
        qv(iu) = load%fx
        du = q(idu)
        dw = q(idw)
        if (load%moment_form == FE_MOMENT_EXACT) then
            r2 = (1.0_dp + du)**2 + dw*dw
        else
            r2 = 1.0_dp
        end if
        qv(idw) = load%moment*(1.0_dp + du)/r2
        qv(idu) = -load%moment*dw/r2
    end subroutine fe_tip_load

    !> kb += scale * dQ/dq for the tip load (only the moment depends on q).
    pure subroutine fe_tip_load_jacobian(mesh, q, load, scale, kb)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        type(fe_load_t), intent(in) :: load
        real(dp), intent(in) :: scale
        real(dp), intent(inout) :: kb(:, :)
        real(dp) :: x, y, r2, m
        integer :: iw, iu, idw, idu
        call tip_indices(mesh, iw, idw, iu, idu)
        m = scale*load%moment
        if (m == 0.0_dp) return
        x = 1.0_dp + q(idu)
        y = q(idw)
        if (load%moment_form == FE_MOMENT_EXACT) then
            ! Q = M grad(Psi), Psi = atan2(y, x): dQ/dq = M Hessian(Psi)
            r2 = x*x + y*y
            call band_add(kb, mesh%kl, mesh%ku, idw, idw, -m*2.0_dp*x*y/r2**2)
            call band_add(kb, mesh%kl, mesh%ku, idu, idu, m*2.0_dp*x*y/r2**2)
            call band_add(kb, mesh%kl, mesh%ku, idw, idu, m*(y*y - x*x)/r2**2)
            call band_add(kb, mesh%kl, mesh%ku, idu, idw, m*(y*y - x*x)/r2**2)
        else
            ! Eq. 78: Q_w' = M (1 + u'), Q_u' = -M w' (not a gradient: unsymmetric)
            call band_add(kb, mesh%kl, mesh%ku, idw, idu, m)
            call band_add(kb, mesh%kl, mesh%ku, idu, idw, -m)
        end if
    end subroutine fe_tip_load_jacobian

    !> Radial wire of length Lw from the tip to the root (Eq. 22, Figure 8),
    !! in the finite element model: the tip sits at x = (L + u, w) (L the
    !! undeformed arm, u and w the tip's displacements), the wire holds it on
    !! the circle |x| = Lw with the tension T, and pulls it with P = -T e,
    !! e = x/|x| (no moment: Eq. 23's zero tip moment). The constraint
    !! g(q) = |x| - Lw has the gradient e on (u, w) of the tip and the Hessian
    !! (I - e e^T)/|x|: the equilibrium is stationary for U(q) + T g(q). This
    !! returns the free indices iu, iw of the tip's u and w, x and r = |x|.
    pure subroutine fe_wire_tip(mesh, q, iu, iw, x, r)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:)
        integer, intent(out) :: iu, iw
        real(dp), intent(out) :: x(2), r
        integer :: idw, idu
        call tip_indices(mesh, iw, idw, iu, idu)
        x = [mesh%s(mesh%nnode) + q(iu), q(iw)]
        r = hypot(x(1), x(2))
    end subroutine fe_wire_tip

    !> Generalized force of the wire at tension T on the free unknowns (as
    !! fe_tip_load's Q): -T e on the tip's u and w.
    pure subroutine fe_wire_force(mesh, q, tension, qv)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:), tension
        real(dp), intent(out) :: qv(:)
        real(dp) :: x(2), r
        integer :: iu, iw
        call fe_wire_tip(mesh, q, iu, iw, x, r)
        qv = 0.0_dp
        qv(iu) = -tension*x(1)/r
        qv(iw) = -tension*x(2)/r
    end subroutine fe_wire_force

    !> kb += scale * dQ/dq of the wire at the fixed tension T: the wire turns
    !! with the tip, dQ/dx = -T (I - e e^T)/|x| (so the tangent d(NLT - Q)/dq
    !! gains the wire's geometric stiffness T (I - e e^T)/|x|, a restoring
    !! stiffness across the wire, none along it).
    pure subroutine fe_wire_jacobian(mesh, q, tension, scale, kb)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:), tension, scale
        real(dp), intent(inout) :: kb(:, :)
        real(dp) :: x(2), r, e(2), g
        integer :: iu, iw
        call fe_wire_tip(mesh, q, iu, iw, x, r)
        e = x/r
        g = -scale*tension/r
        call band_add(kb, mesh%kl, mesh%ku, iu, iu, g*(1.0_dp - e(1)*e(1)))
        call band_add(kb, mesh%kl, mesh%ku, iu, iw, -g*e(1)*e(2))
        call band_add(kb, mesh%kl, mesh%ku, iw, iu, -g*e(1)*e(2))
        call band_add(kb, mesh%kl, mesh%ku, iw, iw, g*(1.0_dp - e(2)*e(2)))
    end subroutine fe_wire_jacobian

    !> Directional derivative (dK_T/dq)[v] of the tangent of fe_tangent (the
    !! elements and the hinge springs) along the free vector v, in band
    !! storage, hand-coded (fe_element_tangent_dir, fe_hinge_tangent_dir).
    pure subroutine fe_tangent_dir(mesh, q, v, kb)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:), v(:)
        real(dp), intent(out) :: kb(:, :)
        real(dp) :: qpad(0:mesh%nfree), vpad(0:mesh%nfree), qe(FE_NDOF), ve(FE_NDOF), &
                    ke(FE_NDOF, FE_NDOF), ks(4, 4), flex
        integer :: el, j, idx(4)
        call pad_free(q, qpad)
        call pad_free(v, vpad)
        kb = 0.0_dp
        do el = 1, mesh%nel
            call element_vector(mesh, qpad, el, qe)
            call element_vector(mesh, vpad, el, ve)
            call fe_element_tangent_dir(mesh%h(el), mesh%ea(el), mesh%ei(el), mesh%cubic(el), &
                                        mesh%xg, mesh%wg, qe, ve, ke)
            call band_scatter(kb, mesh%kl, mesh%ku, mesh%el_free(:, el), ke)
        end do
        do j = merge(0, 1, mesh%root_flex > 0.0_dp), mesh%nhinge
            call fe_spring_dofs(mesh, j, idx, flex)
            call fe_hinge_tangent_dir(flex, qpad(idx), vpad(idx), ks)
            call band_scatter(kb, mesh%kl, mesh%ku, idx, ks)
        end do
    end subroutine fe_tangent_dir

    !> Directional derivative (dM/dq)[v] of fe_mass(mesh, q, .true., mb)
    !! along v: only the rotary inertia's block of Eq. 132 depends on q,
    !! J [2(1+u') du', -(dw'(1+u') + w' du'); ., 2 w' dw'].
    pure subroutine fe_mass_dir(mesh, q, v, mb)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:), v(:)
        real(dp), intent(out) :: mb(:, :)
        real(dp) :: du, dw, vu, vw, jm
        integer :: node, iw, iu
        mb = 0.0_dp
        do node = 2, mesh%nnode
            if (mesh%node_inertia(node) == 0.0_dp) cycle
            jm = mesh%node_inertia(node)
            iw = mesh%free_of(4*(node - 1) + DOF_DW)
            iu = mesh%free_of(4*(node - 1) + DOF_DU)
            du = q(iu)
            dw = q(iw)
            vu = v(iu)
            vw = v(iw)
            call band_add(mb, mesh%kl, mesh%ku, iw, iw, 2.0_dp*jm*(1.0_dp + du)*vu)
            call band_add(mb, mesh%kl, mesh%ku, iw, iu, -jm*(vw*(1.0_dp + du) + dw*vu))
            call band_add(mb, mesh%kl, mesh%ku, iu, iw, -jm*(vw*(1.0_dp + du) + dw*vu))
            call band_add(mb, mesh%kl, mesh%ku, iu, iu, 2.0_dp*jm*dw*vw)
        end do
    end subroutine fe_mass_dir

    !> kb += scale * (d2Q/dq2)[v] of the tip load along v (the exact tip
    !! moment's M Hessian(Psi) moves with the tip slopes; the forces and
    !! the Eq. 78 moment's Jacobian are constant).
    pure subroutine fe_tip_load_jacobian_dir(mesh, q, v, load, scale, kb)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:), v(:)
        type(fe_load_t), intent(in) :: load
        real(dp), intent(in) :: scale
        real(dp), intent(inout) :: kb(:, :)
        real(dp) :: m, ha, hb, dha, dhb
        integer :: iw, iu, idw, idu
        call tip_indices(mesh, iw, idw, iu, idu)
        m = scale*load%moment
        if (m == 0.0_dp .or. load%moment_form /= FE_MOMENT_EXACT) return
        call fe_angle_hessian_dir(1.0_dp + q(idu), q(idw), v(idu), v(idw), ha, hb, dha, dhb)
        call band_add(kb, mesh%kl, mesh%ku, idw, idw, m*dha)
        call band_add(kb, mesh%kl, mesh%ku, idu, idu, -m*dha)
        call band_add(kb, mesh%kl, mesh%ku, idw, idu, m*dhb)
        call band_add(kb, mesh%kl, mesh%ku, idu, idw, m*dhb)
    end subroutine fe_tip_load_jacobian_dir

    !> kb += scale * (d/dq of fe_wire_jacobian's dQ/dq)[v] at the fixed
    !! tension T: with x the tip, r = |x|, dx = v on the tip's (u, w),
    !! d[(I - x x^T/r^2)/r] = -(x.dx) I/r^3 - (dx x^T + x dx^T)/r^3
    !! + 3 (x.dx) x x^T/r^5, times -T (the change of T itself is the
    !! caller's: dT H).
    pure subroutine fe_wire_jacobian_dir(mesh, q, v, tension, scale, kb)
        type(fe_mesh_t), intent(in) :: mesh
        real(dp), intent(in) :: q(:), v(:), tension, scale
        real(dp), intent(inout) :: kb(:, :)
        real(dp) :: x(2), r, dx(2), xdx, g, dh(2, 2)
        integer :: iu, iw, i, j, idx(2)
        call fe_wire_tip(mesh, q, iu, iw, x, r)
        idx = [iu, iw]
        dx = v(idx)
        xdx = dot_product(x, dx)
        g = -scale*tension
        do j = 1, 2
            do i = 1, 2
                dh(i, j) = -(dx(i)*x(j) + x(i)*dx(j))/r**3 + 3.0_dp*xdx*x(i)*x(j)/r**5
            end do
            dh(j, j) = dh(j, j) - xdx/r**3
        end do
        do j = 1, 2
            do i = 1, 2
                call band_add(kb, mesh%kl, mesh%ku, idx(i), idx(j), g*dh(i, j))
            end do
        end do
    end subroutine fe_wire_jacobian_dir

    pure subroutine tip_indices(mesh, iw, idw, iu, idu)
        type(fe_mesh_t), intent(in) :: mesh
        integer, intent(out) :: iw, idw, iu, idu
        iw = mesh%free_of(mesh%node_dof(DOF_W, mesh%nnode))
        idw = mesh%free_of(mesh%node_dof(DOF_DW, mesh%nnode))
        iu = mesh%free_of(mesh%node_dof(DOF_U, mesh%nnode))
        idu = mesh%free_of(mesh%node_dof(DOF_DU, mesh%nnode))
    end subroutine tip_indices

end module beamid_fe_assembly
