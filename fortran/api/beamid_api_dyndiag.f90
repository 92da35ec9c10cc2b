!> f2py-facing API for diagnosing fits with time histories (issue 14):
!! beamid_dyn_diagnosis on the mixed static + release problems of
!! beamid_inverse (experiments as kind and NEXPVAL EV_* values, rows as
!! experiment, t, quantity, value, sigma; 1-based indices; arrays that may
!! be empty carry one unused trailing entry).
module beamid_api_dyndiag
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, status_out, STATUS_OK
    use beamid_estimation, only: fit_options_t, fit_result_t, prior_t, candidate_t, &
                                 diagnose_options_t, diagnosis_t
    use beamid_inverse, only: inverse_problem_t, inverse_problem_init, inverse_diagnose, &
                              EXP_RELEASE
    use beamid_dyn_diagnosis, only: mesh_test_t, dyn_diagnose, time_structure
    implicit none
    private

    public :: api_problem_diagnose, api_time_structure

contains

    !> Structure in time of one series of normalized residuals
    !! (beamid_dyn_diagnosis time_structure; out layout there).
    subroutine api_time_structure(n, t, r, out)
        integer(c_int), intent(in) :: n
        real(c_double), intent(in) :: t(n), r(n)
        real(c_double), intent(out) :: out(10)
        real(dp) :: o(10)
        call time_structure(real(t, dp), real(r, dp), o)
        out = o
    end subroutine api_time_structure

    subroutine make_prior(nprior, prior_idx, prior_mean, prior_sigma, prior)
        integer(c_int), intent(in) :: nprior
        integer(c_int), intent(in) :: prior_idx(:)
        real(c_double), intent(in) :: prior_mean(:), prior_sigma(:)
        type(prior_t), intent(out) :: prior
        prior%index = int(prior_idx(1:nprior))
        prior%mean = real(prior_mean(1:nprior), dp)
        prior%sigma = real(prior_sigma(1:nprior), dp)
    end subroutine make_prior

    !> Diagnose a fit (the one diagnose binding): with release experiments
    !! beamid_dyn_diagnosis dyn_diagnose, of static experiments alone
    !! beamid_inverse inverse_diagnose. The base fit is evaluated at
    !! `params0` (the estimates; not refitted), every candidate block
    !! cand_params(cand_start(c):cand_start(c+1)-1) is score-tested and the
    !! leading ones refitted (from the first-order estimate, from the user's
    !! starting values `nominal` and by continuation). Result columns by
    !! name: api_code_names tables 6-9 (cstats 18 values per candidate, pstats
    !! 6 per candidate parameter, dstats 6); refit_start(c) the start the
    !! refit kept (START_*, 0: none), `notes` one line per candidate (what
    !! the refit starts gave); candidate state 4 (CAND_NOT_SEEN)
    !! for effects the data rows do not see, and
    !! sep_t(c): the time of the probe row separating rival c from the verdict;
    !! mstats = done, ok, elements per beam, recommended, refined chi2, drop,
    !!   p, largest change / sigma, its data row, significant (10 values);
    !! mesh_params: the refined refit's parameters.
    subroutine api_problem_diagnose(nbeams, nparams, params0, nominal, nfree, free_idx, &
                                    nprior, prior_idx, prior_mean, prior_sigma, nexp, exp_kind, &
                                    nval, exp_values, nrow, row_exp, row_t, row_q, row_value, &
                                    row_sigma, tol, max_iter, ncand, cand_start, ncandp, &
                                    cand_params, alpha, nrefit, ambiguity_delta, collinear, &
                                    with_mesh, cstats, pstats, refit_params, ranking, cosine, &
                                    dstats, refit_start, sep_t, mstats, mesh_params, kept, &
                                    notes, code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nfree, nprior, nexp, nrow, max_iter
        integer(c_int), intent(in) :: nval  !< values per experiment (beamid_inverse NEXPVAL)
        real(c_double), intent(in) :: params0(nparams), nominal(nparams)
        real(c_double), intent(in) :: prior_mean(nprior + 1), prior_sigma(nprior + 1)
        integer(c_int), intent(in) :: free_idx(nfree), prior_idx(nprior + 1)
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        real(c_double), intent(in) :: exp_values(nval, nexp), row_t(nrow), row_value(nrow)
        real(c_double), intent(in) :: row_sigma(nrow), tol
        integer(c_int), intent(in) :: ncand, ncandp, nrefit, with_mesh
        integer(c_int), intent(in) :: cand_start(ncand + 1), cand_params(ncandp + 1)
        real(c_double), intent(in) :: alpha, ambiguity_delta, collinear
        real(c_double), intent(out) :: cstats(18, ncand), pstats(6, ncandp + 1)
        real(c_double), intent(out) :: refit_params(nparams, ncand), cosine(ncand, ncand)
        integer(c_int), intent(out) :: ranking(ncand), refit_start(ncand)
        real(c_double), intent(out) :: dstats(6), sep_t(ncand), mstats(10)
        real(c_double), intent(out) :: mesh_params(nparams)
        !> 1: the candidate parameter was tested, 0: left at null (not needed
        !! or not determined), 2: left at null although about as good alone as
        !! the member tested (these data hardly tell them apart)
        integer(c_int), intent(out) :: kept(ncandp + 1)
        character(len=8192), intent(out) :: notes
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(status_t) :: stat
        type(fit_options_t) :: opts
        type(diagnose_options_t) :: dopts
        type(fit_result_t) :: base
        type(prior_t) :: prior
        type(diagnosis_t) :: diag
        type(mesh_test_t) :: mesh
        type(inverse_problem_t) :: model
        type(candidate_t), allocatable :: cands(:), used(:)
        integer, allocatable :: pexp(:), pq(:), ambiguous(:)
        real(dp), allocatable :: pt(:)
        character(len=:), allocatable :: text
        integer :: c, k, j, nf, r, u

        cstats = 0.0_c_double
        pstats = 0.0_c_double
        refit_params = 0.0_c_double
        cosine = 0.0_c_double
        ranking = 0
        refit_start = 0
        dstats = 0.0_c_double
        sep_t = 0.0_c_double
        mstats = 0.0_c_double
        mesh_params = params0
        kept = 0
        notes = ''
        if (max_iter > 0) opts%max_iter = int(max_iter)
        call make_prior(nprior, prior_idx, prior_mean, prior_sigma, prior)
        allocate (cands(ncand))
        do c = 1, ncand
            cands(c)%name = 'candidate'
            cands(c)%params = int(cand_params(cand_start(c):cand_start(c + 1) - 1))
        end do
        dopts%alpha = alpha
        dopts%nrefit = int(nrefit)
        dopts%ambiguity_delta = ambiguity_delta
        dopts%collinear = collinear
        if (any(exp_kind == EXP_RELEASE)) then
            call dyn_diagnose(int(nbeams), int(exp_kind), real(exp_values, dp), int(row_exp), &
                              real(row_t, dp), int(row_q), real(tol, dp), real(row_value, dp), &
                              real(row_sigma, dp), real(params0, dp), real(nominal, dp), &
                              int(free_idx), prior, cands, opts, dopts, with_mesh /= 0, base, &
                              diag, mesh, pexp, pt, pq, used, stat, ambiguous)
        else
            ! static experiments only: the static diagnosis (beamid_inverse;
            ! dyn_diagnose's block reduction and one-sided columns would move
            ! the static results), every block tested as given
            call inverse_problem_init(int(nbeams), int(exp_kind), real(exp_values, dp), &
                                      int(row_exp), real(row_t, dp), int(row_q), &
                                      real(tol, dp), model, stat)
            if (stat%code == STATUS_OK) &
                call inverse_diagnose(model, real(row_value, dp), real(row_sigma, dp), &
                                      real(params0, dp), real(nominal, dp), int(free_idx), &
                                      prior, cands, opts, dopts, base, diag, pexp, pq, stat)
            used = cands
            allocate (ambiguous(0))
            if (allocated(pexp)) allocate (pt(size(pexp)), source=0.0_dp)
        end if
        call status_out(stat, code, message)
        if (stat%code /= STATUS_OK) return
        nf = size(base%free)
        text = ''
        do c = 1, ncand
            associate (cr => diag%cand(c))
                r = cr%separating_row
                cstats(:, c) = [real(cr%state, dp), cr%score%drop, cr%score%p_value, &
                                real(cr%score%dof, dp), b2r(cr%score%physical), &
                                b2r(cr%score%identifiable), b2r(cr%refit_done), &
                                b2r(cr%refit_ok), cr%lr_drop, cr%lr_p, b2r(cr%significant), &
                                b2r(cr%acceptable), b2r(cr%rival), cr%separation, &
                                real(merge(pexp(max(r, 1)), 0, r > 0), dp), &
                                real(merge(pq(max(r, 1)), 0, r > 0), dp), 0.0_dp, 0.0_dp]
                if (r > 0) sep_t(c) = pt(r)
                if (cr%refit_ok) then
                    cstats(17, c) = cr%refit%chi2
                    cstats(18, c) = cr%refit%chi2_prior
                    refit_params(:, c) = cr%refit%params
                end if
                refit_start(c) = int(cr%info%start, c_int)
                if (c > 1) text = text//new_line('a')
                if (cr%refit_done .and. allocated(cr%info%note)) text = text//cr%info%note
                do j = 1, cand_start(c + 1) - cand_start(c)
                    k = cand_start(c) + j - 1
                    ! position of this parameter in the block as tested
                    u = findloc(used(c)%params, cands(c)%params(j), 1)
                    if (u == 0 .and. any(ambiguous == cands(c)%params(j))) kept(k) = 2
                    if (u == 0) cycle
                    kept(k) = 1
                    if (allocated(cr%score%estimate)) then
                        pstats(1:3, k) = [cr%score%estimate(u), cr%score%sigma(u), &
                                          b2r(cr%score%active(u))]
                    end if
                    if (cr%refit_ok) then
                        pstats(4:6, k) = [cr%refit%params(used(c)%params(u)), &
                                          cr%refit%sigmas(nf + u), &
                                          real(cr%refit%flags(nf + u), dp)]
                    end if
                end do
            end associate
        end do
        notes = text
        ranking = int(diag%ranking, c_int)
        cosine = diag%cosine
        dstats = [real(diag%verdict, dp), real(diag%ntested, dp), diag%alpha_each, base%chi2, &
                  base%chi2_prior, real(base%dof, dp)]
        mstats = [b2r(mesh%done), b2r(mesh%ok), real(mesh%nepb, dp), real(mesh%recommended, dp), &
                  mesh%chi2, mesh%drop, mesh%p_value, mesh%max_change, real(mesh%max_row, dp), &
                  b2r(mesh%significant)]
        if (allocated(mesh%params)) mesh_params = mesh%params
    contains
        pure real(dp) function b2r(flag)
            logical, intent(in) :: flag
            b2r = merge(1.0_dp, 0.0_dp, flag)
        end function b2r
    end subroutine api_problem_diagnose
end module beamid_api_dyndiag
