!> Modal experiments (issue 27): the experiment family of a modal test, the
!! arm held by a tip load (none, a force, an exact moment) or a radial wire, and its modes
!! about that equilibrium measured (beamid_modal). Rows are `freq[k]` (Hz),
!! `damping[k]` (ratio; damped models only) and mode shape entries
!! `shape_n@b:s[k]`, `shape_t@...`, `shape_psi@...`, `shape_strain@...`,
!! mode k the k-th lowest mode of the model. The shape rows of one mode in
!! one experiment form its measured shape vector: the predictions are the
!! model's mode sampled at those stations, scaled to unit 2-norm with its
!! first entry (the mode's first shape row in data order) positive; the
!! measured entries are normalized alike and their largest entry is written
!! first (beamid.modal_rows), so the sign is read where the mode moves most
!! and cannot flip between nearly equal entries. Their Jacobian is that
!! normalization's derivative. A shape row needs a frequency row of the same mode in the
!! same experiment (the pairing of measured and model modes is made on the
!! frequencies and shapes before the fit, beamid.pair_modes).
module beamid_modal_experiments
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK, ERR_INPUT, set_status, fmt_int, fmt_real
    use beamid_model, only: chain_t, chain_from_vector
    use beamid_family, only: experiment_family_t, family_input_t, EV_FX, EV_FY, EV_MOMENT, &
                             EV_NEPB, EV_FD, EV_WIRE_LENGTH
    use beamid_observations, only: observation_t, observation_why_not, why_detail, kind_label, &
                                   obs_label, FAM_MODAL, WHY_OK, K_FREQ, K_DAMPING, &
                                   K_SHAPE_N, K_SHAPE_T, K_SHAPE_PSI, K_SHAPE_STRAIN
    use beamid_fe_assembly, only: fe_mesh_t, fe_mesh_build, fe_load_t, FE_MOMENT_EXACT
    use beamid_modal, only: modal_spec_t, modal_out_t, modal_solve, modal_station, &
                            modal_station_sens, modal_param_effect, MP_INVERSE, SHAPE_N, &
                            SHAPE_T, SHAPE_PSI, SHAPE_STRAIN
    implicit none
    private

    public :: modal_exp_t, modal_experiments_t, modal_experiments_init, check_modal_row

    !> The compliance (rad per N m) of the one-sided difference column of a
    !! compliance at 0: a hinge spring some 2000 times stiffer than the arm's
    !! bending stiffness per element length (EI / h ~ 60 N m): the
    !! change it makes (1e-4 of a frequency) stands well above the round-off
    !! of the lowest eigenvalues (1e-7), the curvature of the response costs
    !! about 1e-3 of the column (enough for a score test; 3e-4 measured
    !! against the analytic column at root_flex = 1e-6).
    real(dp), parameter :: NULL_FLEX_STEP = 1.0e-5_dp
    !> One modal experiment: the static load held during the test and the mesh.
    type :: modal_exp_t
        real(dp) :: fx = 0.0_dp, fy = 0.0_dp, moment = 0.0_dp
        !> a radial wire's length (m; 0: none), held on during the test
        real(dp) :: wire_length = 0.0_dp
        integer :: nepb = 4
        !> central-difference columns (the benchmark's baseline, EV_FD = 1)
        logical :: fd = .false.
    end type modal_exp_t

    !> Modal experiments and the data rows they predict.
    !! (the family of experiment kind EXP_MODAL, registered in beamid_families)
    type, extends(experiment_family_t) :: modal_experiments_t
        type(modal_exp_t), allocatable :: exps(:)
    contains
        procedure :: evaluate => modal_evaluate
        procedure :: build => modal_build
    end type modal_experiments_t

contains

    !> Build from the specs (fx, fy, moment, wire_length,
    !! elements_per_beam, fd).
    subroutine modal_build(self, input, stat)
        class(modal_experiments_t), intent(inout) :: self
        type(family_input_t), intent(in) :: input
        type(status_t), intent(inout) :: stat
        type(modal_exp_t), allocatable :: mods(:)
        integer :: e
        allocate (mods(size(input%kinds)))
        do e = 1, size(input%kinds)
            associate (v => input%specs(e))
                mods(e) = modal_exp_t(fx=v%get(EV_FX), fy=v%get(EV_FY), &
                                      moment=v%get(EV_MOMENT), &
                                      wire_length=v%get(EV_WIRE_LENGTH), &
                                      nepb=v%get_int(EV_NEPB), fd=v%get_int(EV_FD) == 1)
            end associate
        end do
        call modal_experiments_init(input, mods, self, stat)
    end subroutine modal_build

    !> Why observation o cannot be a row of a modal experiment ('' when it can).
    pure function check_modal_row(t, o, nbeams) result(why)
        real(dp), intent(in) :: t
        type(observation_t), intent(in) :: o
        integer, intent(in) :: nbeams
        character(len=:), allocatable :: why
        integer :: reason
        why = ''
        if (t /= 0.0_dp) then
            why = 'field t = '//fmt_real(t)//', expected 0 for a modal experiment'
            return
        end if
        reason = observation_why_not(o, FAM_MODAL, .false., .false., nbeams, [real(dp) ::])
        if (reason /= WHY_OK) why = "field quantity = '"//kind_label(o%kind)//"': "// &
            why_detail(o, reason, FAM_MODAL, nbeams, [real(dp) ::])
    end function check_modal_row

    !> Set up and validate the experiments and rows: each row a modal kind,
    !! each shape row with a frequency row of its mode in its experiment.
    subroutine modal_experiments_init(input, exps, self, stat)
        type(family_input_t), intent(in) :: input
        type(modal_exp_t), intent(in) :: exps(:)
        type(modal_experiments_t), intent(out) :: self
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'modal experiments'
        character(len=:), allocatable :: why
        integer :: i, j
        logical :: found
        do i = 1, size(input%row_exp)
            why = check_modal_row(input%row_t(i), input%row_obs(i), input%nbeams)
            if (len(why) > 0) then
                call set_status(stat, ERR_INPUT, where, 'row '//fmt_int(i)//': '//why)
                return
            end if
            if (shape_kind(input%row_obs(i)%kind) == 0) cycle
            found = .false.
            do j = 1, size(input%row_exp)
                if (input%row_exp(j) == input%row_exp(i) .and. &
                    input%row_obs(j)%kind == K_FREQ .and. &
                    input%row_obs(j)%mode == input%row_obs(i)%mode) found = .true.
            end do
            if (.not. found) then
                call set_status(stat, ERR_INPUT, where, 'row '//fmt_int(i)//': shape entry '// &
                                obs_label(input%row_obs(i))//' has no frequency row freq['// &
                                fmt_int(input%row_obs(i)%mode)//'] in its experiment: a mode '// &
                                'shape belongs to a measured mode, expected its frequency too')
                return
            end if
        end do
        self%exps = exps
    end subroutine modal_experiments_init

    !> beamid_modal's SHAPE_* of a shape kind, 0 for the others.
    elemental integer function shape_kind(kind) result(code)
        integer, intent(in) :: kind
        select case (kind)
        case (K_SHAPE_N)
            code = SHAPE_N
        case (K_SHAPE_T)
            code = SHAPE_T
        case (K_SHAPE_PSI)
            code = SHAPE_PSI
        case (K_SHAPE_STRAIN)
            code = SHAPE_STRAIN
        case default
            code = 0
        end select
    end function shape_kind

    !> Predictions and their Jacobian (columns wrt) of every row: one modal
    !! analysis per experiment with rows, up to its highest mode. A
    !! compliance at 0 (a locked joint or clamped root, whose derivative
    !! needs a hinge the mesh does not have) gets a one-sided difference
    !! column from a second analysis at the compliance NULL_FLEX_STEP (the
    !! score test of a diagnosis asks for it at its null value).
    subroutine modal_evaluate(self, params, wrt, predictions, jacobian, stat)
        class(modal_experiments_t), intent(inout) :: self
        real(dp), intent(in) :: params(:)
        integer, intent(in) :: wrt(:)
        real(dp), intent(out) :: predictions(:)
        real(dp), intent(out) :: jacobian(:, :)
        type(status_t), intent(inout) :: stat
        type(chain_t) :: chain
        integer, allocatable :: rows(:), cols(:), nulls(:)
        real(dp), allocatable :: p(:), jac(:, :), p2(:), step(:), none(:, :)
        character(len=:), allocatable :: why
        integer :: e, i, c, effect
        predictions = 0.0_dp
        jacobian = 0.0_dp
        call chain_from_vector(self%nbeams, params, chain, stat)
        if (stat%code /= STATUS_OK) return
        allocate (cols(0), nulls(0))
        do c = 1, size(wrt)
            call modal_param_effect(chain, wrt(c), effect, why)
            if (effect == MP_INVERSE .and. params(wrt(c)) == 0.0_dp) then
                nulls = [nulls, c]
            else
                cols = [cols, c]
            end if
        end do
        do e = 1, size(self%exps)
            rows = self%exp_rows(e)
            if (size(rows) == 0) cycle
            if (self%exps(e)%fd) then
                call central_differences(e, rows, stat)
                if (stat%code /= STATUS_OK) return
                cycle
            end if
            allocate (p(size(rows)), jac(size(rows), size(cols)))
            call predict(self, e, rows, params, wrt(cols), p, jac, stat)
            if (stat%code /= STATUS_OK) return
            predictions(rows) = p
            jacobian(rows, cols) = jac
            do i = 1, size(nulls)
                p2 = params
                p2(wrt(nulls(i))) = NULL_FLEX_STEP
                allocate (step(size(rows)), none(size(rows), 0))
                call predict(self, e, rows, p2, [integer ::], step, none, stat)
                if (stat%code /= STATUS_OK) return
                jacobian(rows, nulls(i)) = (step - p)/NULL_FLEX_STEP
                deallocate (step, none)
            end do
            deallocate (p, jac)
        end do
    contains
        !> Every column of experiment e by central differences of whole
        !! analyses (step 1e-3 of the parameter: the lowest eigenvalues carry a
        !! round-off of about eps lambda_max, 1e-7 relative, which a smaller
        !! step turns into noisy columns; forward from a null value).
        subroutine central_differences(e, rows, stat)
            integer, intent(in) :: e, rows(:)
            type(status_t), intent(inout) :: stat
            real(dp) :: pc(size(rows)), pp(size(rows)), pm(size(rows)), h, none(size(rows), 0)
            real(dp) :: q(size(params))
            integer :: c
            call predict(self, e, rows, params, [integer ::], pc, none, stat)
            if (stat%code /= STATUS_OK) return
            predictions(rows) = pc
            do c = 1, size(wrt)
                h = 1.0e-3_dp*abs(params(wrt(c)))
                q = params
                if (h == 0.0_dp) then
                    h = 1.0e-8_dp
                    q(wrt(c)) = h
                    call predict(self, e, rows, q, [integer ::], pp, none, stat)
                    if (stat%code /= STATUS_OK) return
                    jacobian(rows, c) = (pp - pc)/h
                    cycle
                end if
                q(wrt(c)) = params(wrt(c)) + h
                call predict(self, e, rows, q, [integer ::], pp, none, stat)
                if (stat%code /= STATUS_OK) return
                q(wrt(c)) = params(wrt(c)) - h
                call predict(self, e, rows, q, [integer ::], pm, none, stat)
                if (stat%code /= STATUS_OK) return
                jacobian(rows, c) = (pp - pm)/(2.0_dp*h)
            end do
        end subroutine central_differences
    end subroutine modal_evaluate

    !> Rows `rows` of experiment e (predictions p, Jacobian jac, columns wrt).
    subroutine predict(self, e, rows, params, wrt, p, jac, stat)
        type(modal_experiments_t), intent(in) :: self
        integer, intent(in) :: e, rows(:), wrt(:)
        real(dp), intent(in) :: params(:)
        real(dp), intent(out) :: p(:), jac(:, :)
        type(status_t), intent(inout) :: stat
        type(modal_spec_t) :: spec
        type(modal_out_t) :: out
        type(chain_t) :: chain
        type(fe_mesh_t) :: mesh
        integer, allocatable :: srows(:)
        real(dp), allocatable :: v(:), dv(:, :), u(:)
        real(dp) :: nrm, sgn
        integer :: i, j, k, r, nmodes, kk
        p = 0.0_dp
        jac = 0.0_dp
        call chain_from_vector(self%nbeams, params, chain, stat)
        if (stat%code /= STATUS_OK) return
        spec%elements_per_beam = self%exps(e)%nepb
        spec%load = fe_load_t(self%exps(e)%fx, self%exps(e)%fy, self%exps(e)%moment, &
                              FE_MOMENT_EXACT)
        spec%wire_length = self%exps(e)%wire_length
        nmodes = maxval(self%row_obs(rows)%mode)
        call modal_solve(self%nbeams, params, spec, nmodes, wrt, out, stat)
        if (stat%code /= STATUS_OK) then
            stat%message = 'modal experiment '//fmt_int(e)//': '//stat%message
            return
        end if
        call fe_mesh_build(chain, spec%elements_per_beam, mesh, stat)
        if (stat%code /= STATUS_OK) return
        do i = 1, size(rows)
            r = rows(i)
            k = self%row_obs(r)%mode
            select case (self%row_obs(r)%kind)
            case (K_FREQ)
                p(i) = out%freq(k)
                jac(i, :) = out%dfreq(k, :)
            case (K_DAMPING)
                if (.not. out%damped) then
                    call set_status(stat, ERR_INPUT, 'modal experiments', 'row '// &
                                    fmt_int(r)//': damping['//fmt_int(k)//'] asked of '// &
                                    'an undamped model (no drag c_* and no Kelvin-Voigt '// &
                                    'eta): expected a damping effect in the model or no '// &
                                    'damping rows')
                    return
                end if
                p(i) = out%zeta(k)
                jac(i, :) = out%dzeta(k, :)
            end select
        end do
        ! shapes: per mode, its rows normalized together (indices into rows)
        do k = 1, nmodes
            srows = pack([(i, i=1, size(rows))], shape_kind(self%row_obs(rows)%kind) > 0 .and. &
                         self%row_obs(rows)%mode == k)
            if (size(srows) == 0) cycle
            allocate (v(size(srows)), dv(size(srows), size(wrt)))
            do i = 1, size(srows)
                r = rows(srows(i))
                kk = shape_kind(self%row_obs(r)%kind)
                v(i) = modal_station(mesh, out%q, out%phi(:, k), kk, self%row_obs(r)%beam, &
                                     self%row_obs(r)%s, chain%thickness(self%row_obs(r)%beam))
                do j = 1, size(wrt)
                    dv(i, j) = modal_station_sens(mesh, out, k, j, kk, self%row_obs(r)%beam, &
                                                  self%row_obs(r)%s)
                end do
            end do
            nrm = norm2(v)
            if (.not. (nrm > 0.0_dp)) then
                call set_status(stat, ERR_INPUT, 'modal experiments', 'experiment '// &
                                fmt_int(e)//': mode '//fmt_int(k)//' is zero at every '// &
                                'shape station of its rows: expected stations where it moves')
                return
            end if
            ! the sign: the mode's first shape row (in data order) positive, the
            ! row modal_rows puts first, where the measured mode moves most
            ! (the largest entry when the first is zero)
            if (v(1) /= 0.0_dp) then
                sgn = sign(1.0_dp, v(1))
            else
                sgn = sign(1.0_dp, v(maxloc(abs(v), 1)))
            end if
            u = v/nrm
            p(srows) = sgn*u
            do j = 1, size(wrt)
                jac(srows, j) = sgn*(dv(:, j) - u*dot_product(u, dv(:, j)))/nrm
            end do
            deallocate (v, dv)
        end do
    end subroutine predict

end module beamid_modal_experiments
