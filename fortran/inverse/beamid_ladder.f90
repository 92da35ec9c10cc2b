!> The model-improvement workflow on an estimation problem given as arrays
!! (any mix of static and release experiments, beamid_inverse's layout):
!! fit, diagnose, and the improve ladder. Both fronts call it: beamid-batch
!! through beamid_tasks (decks), Python through beamid_api_estimation
!! (beamid.diagnose, beamid.improve), so both write the same ladder.
module beamid_ladder
    use, intrinsic :: iso_fortran_env, only: int64
    use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK, ERR_INPUT, fmt_int, fmt_real, set_status
    use beamid_estimation, only: fit_result_t, fit_options_t, prior_t, candidate_t, &
                                 diagnose_options_t, diagnosis_t, chi2_sf, lsq_problem_t, &
                                 fit_least_squares, STOP_CONVERGED
    use beamid_inverse, only: inverse_problem_t, inverse_problem_init, inverse_lsq, &
                              inverse_diagnose, EXP_RELEASE, EV_NEPB, EV_LOSS, EV_SIGEST, &
                              MAX_CHANNEL_BITS
    use beamid_chain_fit, only: chain_fit, chain_active
    use beamid_families, only: kind_mesh_key
    use beamid_dyn_diagnosis, only: problem_t, dyn_diagnose, mesh_test_t, mesh_test, has_mesh
    implicit none
    private

    public :: problem_t, cand_set_t, diag_out_t, rung_t, ladder_t
    public :: problem_fit, problem_diagnose, problem_dynamic
    public :: ladder_start, ladder_step
    public :: ladder_end_at_fit

    !> A rung's fit ends "far above its degrees of freedom" when the
    !! chi-square's p-value is below this (beamid.robust.FAR_P).
    real(dp), parameter :: FAR_P = 1.0e-3_dp

    !> The candidates of one diagnosis: effects with their parameter blocks;
    !! with releases `mesh` is tested apart (with_mesh).
    type :: cand_set_t
        character(len=32), allocatable :: names(:)
        type(candidate_t), allocatable :: cands(:)
        logical :: with_mesh = .false.
        !> the measurement chain's row candidates of the improve ladder
        !! (row_rung): gross errors (the next rung fits with a Huber loss)
        !! and noise larger than stated (the next rung estimates the sigmas)
        logical :: gross = .false., noise = .false.
    end type cand_set_t

    !> gross errors: at most this share of the rows (and at least 3), as
    !! beamid.chain.GROSS_SHARE
    real(dp), parameter :: GROSS_SHARE = 0.02_dp

    !> One diagnosis: the base fit, the library's report and the probe rows.
    type :: diag_out_t
        type(fit_result_t) :: base
        type(diagnosis_t) :: diag
        integer, allocatable :: pexp(:), pq(:)
        real(dp), allocatable :: pt(:)    !< probe row times (0 for static probes)
        logical :: dynamic = .false.      !< release experiments: beamid_dyn_diagnosis
        type(mesh_test_t) :: mesh         !< the mesh test (dynamic, when asked)
        !> the blocks as tested (dyn_diagnose: reduced to the members the
        !! data determine; static: as given)
        type(candidate_t), allocatable :: used(:)
        !> parameters left at null about as good alone as the member tested
        integer, allocatable :: ambiguous(:)
    end type diag_out_t

    !> One rung of the improve ladder: the fit, its diagnosis and what the
    !! rung changed.
    type :: rung_t
        character(len=:), allocatable :: effect  !< 'start', the effect, or 'mesh (N ...)'
        type(fit_result_t) :: fit
        type(diag_out_t) :: dg
        real(dp), allocatable :: start(:)    !< where the rung's fit started
        real(dp), allocatable :: nominal(:)  !< the user's model, added parameters as fitted
        integer, allocatable :: params(:)    !< parameters the rung switched on
        integer, allocatable :: removed(:)   !< switched on earlier, back at null here
        integer :: nepb = 0                  !< elements per beam of the releases (0: as given)
        integer :: refit_start = 0           !< START_* of the verdict's refit kept
    end type rung_t

    !> The improve ladder under way (ladder_start, ladder_step): the problem
    !! (its releases refined by the mesh rungs), the candidates, the rungs
    !! done and the next rung's fit.
    type :: ladder_t
        type(problem_t) :: pb
        type(cand_set_t) :: cs
        type(fit_options_t) :: fopts          !< the diagnoses' refits
        type(diagnose_options_t) :: dopts
        real(dp), allocatable :: params(:)    !< the user's model
        real(dp), allocatable :: nominal(:)   !< params, added parameters as fitted
        integer, allocatable :: added(:)      !< parameters the rungs switched on
        integer :: max_steps = 0
        integer :: k = 0                      !< rungs added so far
        type(rung_t) :: r                     !< the rung whose fit is done
        type(rung_t), allocatable :: rungs(:) !< rungs(:n): the rungs diagnosed
        integer :: n = 0
        logical :: done = .true.              !< no further ladder_step
    end type ladder_t

contains

    !> Has the problem a release experiment (time histories)?
    pure logical function problem_dynamic(pb)
        type(problem_t), intent(in) :: pb
        problem_dynamic = any(pb%exp_kind == EXP_RELEASE)
    end function problem_dynamic

    !> Weighted GN/LM fit of params(free) from params0 (Eq. 39, 53-55,
    !! 142-148) with the problem's a priori information or `prior`.
    subroutine problem_fit(pb, params0, free, fo, st, prior)
        type(problem_t), intent(in) :: pb
        real(dp), intent(in) :: params0(:)
        integer, intent(in) :: free(:)
        type(fit_result_t), intent(out) :: fo
        type(status_t), intent(inout) :: st
        type(prior_t), intent(in), optional :: prior
        type(inverse_problem_t) :: problem
        type(fit_options_t) :: opts
        type(lsq_problem_t) :: lp
        type(status_t) :: stat
        real(dp) :: w(size(pb%y)), su(size(pb%y)), sd(size(pb%y))
        logical :: gross(size(pb%y))
        call inverse_problem_init(pb%nbeams, pb%exp_kind, pb%specs, pb%row_exp, pb%row_t, &
                                  pb%row_q, pb%tol, problem, stat, pb%obs, hist=pb%hist)
        if (stat%code == STATUS_OK .and. any(ieee_is_nan(pb%sigma)) .and. &
            .not. chain_active(problem%rows)) &
            call set_status(stat, ERR_INPUT, 'fit', 'sigma missing: row '// &
                            fmt_int(findloc(ieee_is_nan(pb%sigma), .true., 1))// &
                            ' has no sigma and no estimation is asked (estimate_sigma); '// &
                            'expected a sigma > 0 on every row')
        if (stat%code == STATUS_OK) then
            opts%max_iter = pb%max_iter
            lp = inverse_lsq(problem, pb%y, pb%sigma, pb%prior)
            if (present(prior)) lp%prior = prior
            if (chain_active(problem%rows)) then
                ! a loss, burn-in rows or estimated sigmas (keys loss, burn_in,
                ! sigma_est): the chain's fit, as beamid.fit with them
                call chain_fit(problem, lp, params0, free, opts, problem%rows, fo, w, su, sd, &
                               gross, stat)
            else
                call fit_least_squares(problem, lp, params0, free, opts, fo, stat)
            end if
        end if
        if (stat%code /= STATUS_OK) st = stat
    end subroutine problem_fit

    !> The problem as a fit with the chain's row treatments judged it (its
    !! diagnosis sees these rows): each row's sigma as judged (estimated
    !! where asked), burn-in rows and gross errors out (sigma 1e8 times
    !! larger); pb itself after a plain fit.
    function judged_problem(pb, fo) result(out)
        type(problem_t), intent(in) :: pb
        type(fit_result_t), intent(in) :: fo
        type(problem_t) :: out
        out = pb
        if (.not. allocated(fo%row_sigma)) return
        out%sigma = fo%row_sigma
        where (fo%row_weight <= 0.0_dp .or. fo%row_gross) out%sigma = 1.0e8_dp*fo%row_sigma
        ! a plain problem now: the treatments are in its sigmas
        call out%specs%clear_treatment()
    end function judged_problem

    !> Score tests, refits and ranking of the candidates `cs` around the fit
    !! at params(free) (not refitted): with release experiments
    !! dyn_diagnose, of static experiments alone inverse_diagnose (every block
    !! tested as given; dyn_diagnose's block reduction and one-sided columns
    !! would move the static results). The refits also start from `nominal`,
    !! the user's model; `fopts` are the refits' options.
    subroutine problem_diagnose(pb, params, free, nominal, cs, fopts, dopts, dg, st)
        type(problem_t), intent(in) :: pb
        real(dp), intent(in) :: params(:), nominal(:)
        integer, intent(in) :: free(:)
        type(cand_set_t), intent(in) :: cs
        type(fit_options_t), intent(in) :: fopts
        type(diagnose_options_t), intent(in) :: dopts
        type(diag_out_t), intent(out) :: dg
        type(status_t), intent(inout) :: st
        type(inverse_problem_t) :: problem
        type(status_t) :: stat
        type(diagnose_options_t) :: dsub
        logical :: mesh
        dg%dynamic = problem_dynamic(pb)
        if (dg%dynamic) then
            call dyn_diagnose(pb, params, nominal, free, cs%cands, fopts, dopts, cs%with_mesh, &
                              dg%base, dg%diag, dg%mesh, dg%pexp, dg%pt, dg%pq, dg%used, stat, &
                              dg%ambiguous)
        else
            call inverse_problem_init(pb%nbeams, pb%exp_kind, pb%specs, pb%row_exp, &
                                      pb%row_t, pb%row_q, pb%tol, problem, stat, pb%obs, &
                                      hist=pb%hist)
            ! modal tests have a mesh of their own (issue 27): with `mesh`
            ! asked, the mesh test as with releases, one more test in the
            ! Bonferroni level
            mesh = cs%with_mesh .and. has_mesh(pb%exp_kind)
            dsub = dopts
            if (mesh .and. size(cs%cands) > 0) dsub%alpha = dopts%alpha* &
                real(size(cs%cands), dp)/real(size(cs%cands) + 1, dp)
            if (stat%code == STATUS_OK) &
                call inverse_diagnose(problem, inverse_lsq(problem, pb%y, pb%sigma, pb%prior), &
                                      params, nominal, free, cs%cands, fopts, dsub, dg%base, &
                                      dg%diag, dg%pexp, dg%pq, stat)
            if (stat%code == STATUS_OK .and. mesh) &
                call mesh_test(pb, inverse_lsq(problem, pb%y, pb%sigma, pb%prior), dg%base, &
                               fopts, dopts%alpha/real(dg%diag%ntested + 1, dp), dg%mesh, stat)
            dg%used = cs%cands
            allocate (dg%ambiguous(0))
            if (allocated(dg%pexp)) allocate (dg%pt(size(dg%pexp)), source=0.0_dp)
        end if
        if (stat%code /= STATUS_OK) st = stat
    end subroutine problem_diagnose

    !> The improve ladder (beamid.improve): fit params(free), then diagnose
    !! and add the verdict's parameters (a block as tested: dyn_diagnose
    !! tests its other members at the later rungs) until no candidate is
    !! significant at `alpha` or `max_steps` rungs were added (the diagnoses'
    !! defaults: 3 refits of 50 iterations, ambiguity 4, collinearity 0.98;
    !! the refits also start from the user's model with the added parameters
    !! as fitted). With release experiments a significant mesh test refines
    !! every release to the recommended elements per beam (the mesh is tested
    !! until found adequate), and after each rung the parameters earlier
    !! rungs added are tested again (one-sided Wald test at the rung's level):
    !! one no longer needed goes back to its value in `params` and the rung
    !! is refitted without it. ladder_start starts it with the fit of
    !! params(free) (rung 0, diagnosed by the first ladder_step); ladder_step
    !! runs a rung per call (a front that shows progress steps itself).
    subroutine ladder_start(lad, pb, params, free, cs, alpha, max_steps, st)
        type(ladder_t), intent(out) :: lad
        type(problem_t), intent(in) :: pb
        real(dp), intent(in) :: params(:)
        integer, intent(in) :: free(:)
        type(cand_set_t), intent(in) :: cs
        real(dp), intent(in) :: alpha
        integer, intent(in) :: max_steps
        type(status_t), intent(inout) :: st
        lad%pb = pb
        lad%cs = cs
        lad%params = params
        lad%nominal = params
        lad%dopts%alpha = alpha
        lad%fopts%max_iter = 50
        if (max_steps < 0) then
            call set_status(st, ERR_INPUT, 'improve', 'max_steps = '//fmt_int(max_steps)// &
                            ', expected a number of rungs >= 0')
            lad%done = .true.
            return
        end if
        lad%max_steps = max_steps
        ! the rungs grow as they are added (ladder_step): max_steps is a limit,
        ! not a size (a huge limit must not allocate)
        allocate (lad%added(0), lad%rungs(1))
        lad%r%effect = 'start'
        lad%r%start = params
        lad%r%params = [integer ::]
        lad%r%removed = [integer ::]
        call problem_fit(lad%pb, params, free, lad%r%fit, st)
        lad%done = st%code /= STATUS_OK
    end subroutine ladder_start

    !> One rung of the ladder: diagnose the rung's fit and keep the rung
    !! (lad%rungs(lad%n)); unless the ladder ends here (nothing significant,
    !! max_steps rungs added or a failure: lad%done), refine the mesh or add
    !! the verdict's parameters, refit, and set back a parameter no longer
    !! needed (the next rung's fit).
    subroutine ladder_step(lad, st)
        type(ladder_t), intent(inout) :: lad
        type(status_t), intent(inout) :: st
        real(dp), allocatable :: p(:)
        integer, allocatable :: now(:)
        integer :: v, gone, j

        if (lad%done) return
        lad%done = .true.           ! unless the rung ends with the next fit
        if (st%code /= STATUS_OK) return
        associate (r => lad%r, pb => lad%pb, cs => lad%cs)
            r%nominal = lad%nominal
            call problem_diagnose(judged_problem(pb, r%fit), r%fit%params, r%fit%free, &
                                  lad%nominal, cs, lad%fopts, lad%dopts, r%dg, st)
            if (st%code /= STATUS_OK) return
            lad%n = lad%n + 1
            if (lad%n > size(lad%rungs)) lad%rungs = [lad%rungs, r]
            lad%rungs(lad%n) = r
            v = r%dg%diag%verdict
            if (lad%k == lad%max_steps) return
            ! the measurement chain's row candidates: gross errors before any
            ! effect (they would be blamed on the physics), noise larger than
            ! stated when nothing else is found
            if (row_rung(lad, v == 0 .and. .not. r%dg%mesh%significant, st)) then
                lad%done = st%code /= STATUS_OK
                return
            end if
            if (v == 0 .and. .not. r%dg%mesh%significant) return
            lad%k = lad%k + 1
            if (r%dg%mesh%done .and. .not. r%dg%mesh%significant) cs%with_mesh = .false.
            now = r%fit%free    ! (a copy: the fit below overwrites r%fit)
            r%removed = [integer ::]
            if (r%dg%mesh%significant) then
                r%nepb = r%dg%mesh%recommended
                ! every experiment with a mesh of its own: releases, modal tests
                do j = 1, size(pb%exp_kind)
                    if (kind_mesh_key(pb%exp_kind(j)) > 0) &
                        call pb%specs(j)%set(kind_mesh_key(pb%exp_kind(j)), real(r%nepb, dp))
                end do
                r%effect = 'mesh ('//fmt_int(r%nepb)//' elements per beam)'
                r%start = r%fit%params
                r%params = [integer ::]
                r%refit_start = 0
                cs%with_mesh = .false.
                call problem_fit(pb, r%start, now, r%fit, st)
                lad%done = .false.
                return
            end if
            associate (c => r%dg%diag%cand(v))
                r%start = r%fit%params
                if (c%refit_done .and. c%refit_ok) r%start = c%refit%params
                r%refit_start = c%info%start
            end associate
            ! the block as tested, in the candidate's order
            r%params = pack(cs%cands(v)%params, [(any(r%dg%used(v)%params == &
                            cs%cands(v)%params(j)), j=1, size(cs%cands(v)%params))])
            r%effect = trim(cs%names(v))
            call problem_fit(pb, r%start, [now, r%params], r%fit, st)
            if (st%code /= STATUS_OK) return
            if (r%dg%dynamic) then
                gone = not_needed(r%fit, lad%added, r%dg%diag%alpha_each)
                if (gone > 0) then
                    r%removed = [gone]
                    p = r%fit%params
                    p(gone) = lad%params(gone)
                    now = pack(r%fit%free, r%fit%free /= gone)
                    call problem_fit(pb, p, now, r%fit, st)
                    if (st%code /= STATUS_OK) return
                    lad%added = pack(lad%added, lad%added /= gone)
                end if
            end if
            if (r%dg%dynamic) then
                ! (releases: a static fit's minimum does not depend on
                ! where friction switched)
                call rung_at_best(pb, lad%nominal, r, st)
                if (st%code /= STATUS_OK) return
            end if
            lad%added = [lad%added, r%params]
            lad%nominal(r%params) = r%fit%params(r%params)
        end associate
        lad%done = .false.
    end subroutine ladder_step

    !> The next rung of the measurement chain's row candidates, when one is
    !! due (true: lad%r holds its fit): `gross_errors` while asked and the
    !! rung's fit has rows beyond the Bonferroni level alpha / n of the largest
    !! of n normal residuals on the bulk's scale (1.4826 times the median
    !! absolute deviation of the normalized residuals, at least 1; none when
    !! more than GROSS_SHARE of the rows, at least 3, would be): the fit again
    !! with a Huber loss on every experiment (beamid_chain_fit); `noise`, when
    !! asked and `quiet` (no effect found), and the chi-square is above its
    !! degrees of freedom at level alpha: the fit again with every channel's
    !! sigma estimated. Each is tested until added once. As beamid.chain's
    !! gross_rows and diagnose's noise candidate.
    logical function row_rung(lad, quiet, st) result(added)
        type(ladder_t), intent(inout) :: lad
        logical, intent(in) :: quiet
        type(status_t), intent(inout) :: st
        real(dp), allocatable :: z(:), dev(:)
        logical, allocatable :: judged(:)
        real(dp) :: scale, level
        integer :: n, nflag, e, i, q
        added = .false.
        if (.not. problem_dynamic(lad%pb)) return
        associate (r => lad%r, pb => lad%pb, cs => lad%cs)
            level = lad%dopts%alpha
            if (cs%gross) then
                judged = [(.true., i=1, size(r%fit%normalized))]
                if (allocated(r%fit%row_weight)) judged = r%fit%row_weight > 0.0_dp .and. &
                                                          .not. r%fit%row_gross
                z = pack(r%fit%normalized, judged)
                n = size(z)
                if (n >= 5) then
                    dev = abs(z - median(z))
                    scale = max(1.0_dp, 1.4826_dp*median(dev))
                    nflag = 0
                    do i = 1, n
                        if (chi2_sf((z(i)/scale)**2, 1) < level/real(n, dp)) nflag = nflag + 1
                    end do
                    if (nflag > 0 .and. nflag <= max(3, int(GROSS_SHARE*real(n, dp)))) then
                        cs%gross = .false.
                        call pb%specs%set(EV_LOSS, 1.0_dp)          ! Huber
                        call rung_refit(lad, 'gross_errors', st)
                        added = .true.
                        return
                    end if
                end if
            end if
            if (cs%noise .and. quiet .and. r%fit%dof > 0) then
                if (chi2_sf(r%fit%chi2 + r%fit%chi2_prior, r%fit%dof) < level) then
                    cs%noise = .false.
                    do i = 1, size(pb%row_q)
                        e = pb%row_exp(i)
                        q = pb%row_q(i)
                        if (q > MAX_CHANNEL_BITS) cycle
                        if (.not. btest(nint(pb%specs(e)%get(EV_SIGEST), int64), q - 1)) &
                            call pb%specs(e)%set(EV_SIGEST, pb%specs(e)%get(EV_SIGEST) + &
                                                 2.0_dp**(q - 1))
                    end do
                    call rung_refit(lad, 'noise', st)
                    added = .true.
                end if
            end if
        end associate
    end function row_rung

    !> A rung that changes how the rows are treated (row_rung): the rung's fit
    !! again from its estimates, the same parameters free.
    subroutine rung_refit(lad, name, st)
        type(ladder_t), intent(inout) :: lad
        character(len=*), intent(in) :: name
        type(status_t), intent(inout) :: st
        integer, allocatable :: now(:)
        lad%k = lad%k + 1
        associate (r => lad%r)
            now = r%fit%free
            r%effect = name
            r%start = r%fit%params
            r%params = [integer ::]
            r%removed = [integer ::]
            r%refit_start = 0
            call problem_fit(lad%pb, r%start, now, r%fit, st)
        end associate
    end subroutine rung_refit

    !> The median of x.
    pure real(dp) function median(x)
        real(dp), intent(in) :: x(:)
        real(dp) :: y(size(x)), t
        integer :: i, j, n
        y = x
        n = size(y)
        do i = 2, n                    ! insertion sort (a rung's rows: thousands)
            t = y(i)
            j = i - 1
            do while (j >= 1)
                if (y(j) <= t) exit
                y(j + 1) = y(j)
                j = j - 1
            end do
            y(j + 1) = t
        end do
        median = y((n + 1)/2)
        if (mod(n, 2) == 0) median = 0.5_dp*(y(n/2) + y(n/2 + 1))
    end function median

    !> A rung's fit at its best before the ladder goes on (issue 30): when
    !! it ends far above its degrees of freedom (p below FAR_P), the fit is
    !! repeated from the user's model (`nominal`: earlier rungs' parameters
    !! as fitted) with the rung's parameters at their fitted values, so the
    !! parameters fitted before the effect was added (friction absorbing a
    !! root compliance) leave the minimum they found without it. The lower
    !! end point is the rung's fit when it is lower by more than
    !! max(0.05, 1e-5 chi2) (the noise floor of an integrated response); the
    !! fit's note says what the check found.
    subroutine rung_at_best(pb, nominal, r, st)
        type(problem_t), intent(in) :: pb
        real(dp), intent(in) :: nominal(:)
        type(rung_t), intent(inout) :: r
        type(status_t), intent(inout) :: st
        type(fit_result_t) :: again
        type(status_t) :: st2
        real(dp), allocatable :: p(:)
        real(dp) :: c0, c1
        character(len=:), allocatable :: text
        if (.not. allocated(r%fit%params) .or. r%fit%dof <= 0) return
        c0 = r%fit%chi2 + r%fit%chi2_prior
        if (chi2_sf(c0, r%fit%dof) >= FAR_P) return
        p = nominal
        p(r%params) = r%fit%params(r%params)
        if (all(p(r%fit%free) == r%fit%params(r%fit%free))) return
        call problem_fit(pb, p, r%fit%free, again, st2)
        if (st2%code < 0) then
            st = st2           ! bad input is bad input
            return
        end if
        if (st2%code /= STATUS_OK .or. .not. allocated(again%params)) then
            text = 'at its best: the refit from the nominal model failed ('// &
                   trim(st2%message)//')'
        else
            c1 = again%chi2 + again%chi2_prior
            if (again%stop == STOP_CONVERGED .and. c0 - c1 >= max(0.05_dp, 1.0e-5_dp*c1)) then
                text = 'at its best from the nominal model: chi2 '//fmt_real(again%chi2)// &
                       ' where the fit from the diagnosis'' refit ended at '// &
                       fmt_real(r%fit%chi2)//' (a local minimum)'
                r%fit = again
            else
                text = 'at its best: the refit from the nominal model ended at chi2 '// &
                       fmt_real(again%chi2)
            end if
        end if
        if (allocated(r%fit%note)) then
            if (len(r%fit%note) > 0) text = r%fit%note//'; '//text
        end if
        r%fit%note = text
    end subroutine rung_at_best

    !> End a started ladder at its fit, undiagnosed (a fit or compare deck):
    !! the fit is the only rung, with no candidates and an empty diagnosis.
    subroutine ladder_end_at_fit(lad)
        type(ladder_t), intent(inout) :: lad
        type(cand_set_t) :: none
        if (lad%done) return                  ! the fit failed
        ! no candidates, allocated empty (gfortran 12 leaves the components of
        ! a structure constructor from empty array constructors unallocated)
        allocate (none%names(0), none%cands(0))
        lad%cs = none
        allocate (lad%r%dg%diag%ranking(0), lad%r%dg%diag%cosine(0, 0))
        lad%r%nominal = lad%nominal
        lad%n = 1
        lad%rungs(1) = lad%r
        lad%done = .true.
    end subroutine ladder_end_at_fit

    !> Of the parameters `names` (switched on by earlier rungs; one-sided,
    !! physical values positive) the one whose one-sided Wald test
    !! (estimate / sigma) is least significant, when its p-value exceeds
    !! `level` (0: every one is needed).
    integer function not_needed(fo, names, level) result(worst)
        type(fit_result_t), intent(in) :: fo
        integer, intent(in) :: names(:)
        real(dp), intent(in) :: level
        real(dp) :: p, worst_p, est, sig
        integer :: i, j
        worst = 0
        worst_p = level
        do i = 1, size(names)
            j = findloc(fo%free, names(i), 1)
            if (j == 0) cycle
            est = fo%estimates(j)
            sig = fo%sigmas(j)
            p = 1.0_dp
            if (sig > 0.0_dp .and. sig < huge(1.0_dp) .and. est > 0.0_dp) &
                p = 0.5_dp*chi2_sf((est/sig)**2, 1)
            if (p > worst_p) then
                worst = names(i)
                worst_p = p
            end if
        end do
    end function not_needed
end module beamid_ladder
