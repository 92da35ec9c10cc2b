!> f2py-facing API for static estimation and diagnosis (beamid_estimation,
!! beamid_static_experiments).
!!
!! A problem crosses as plain arrays: experiments (load kind and the four
!! load values fx, fy, moment, wire_length per experiment), data rows
!! (experiment index, quantity code, value, sigma), free parameter indices,
!! a priori index/mean/sigma (Eq. 142-145). Indices are 1-based. Status
!! codes follow beamid_status; logical results are 0/1 integers.
module beamid_api_estimation
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, status_out, STATUS_OK, ERR_NO_CONVERGENCE, ERR_INPUT, set_status
    use beamid_arclength, only: static_load_t
    use beamid_estimation, only: residual_structure
    use beamid_estimation, only: fit_options_t, fit_result_t, prior_t, fit_least_squares, &
                                 candidate_t, diagnose_options_t, diagnosis_t, diagnose, &
                                 chi2_sf, fit_at, score_test, score_result_t, refit_effect, &
                                 refit_info_t, FLAG_NAMES, STOP_NAMES, START_NAMES, CAND_NAMES

    use beamid_static_experiments, only: static_experiments_t, static_experiments_init, &
                                         static_bounds, static_null_values, probe_rows
    use beamid_estimation, only: prior_from_covariance, STOP_NAMES
    use beamid_deck, only: deck_t, read_deck
    use beamid_inverse, only: inverse_problem_t, inverse_problem_init, inverse_diagnose, NEXPVAL
    implicit none
    private

    public :: api_static_predict, api_fit, api_chi2_sf, api_static_bounds
    public :: api_residual_structure, api_fit_effect, api_diagnose_nominal, api_code_names
    public :: api_problem_predict, api_problem_fit, api_deck_experiments

    ! notes strings (refit notes of every candidate) are character(len=8192):
    ! f2py needs the length as a literal

    !> The names of the columns of the result arrays (exported by
    !! api_code_names, tables 5-8, so that no front decodes them by position):
    !! stats of a fit, cstats (per candidate), pstats (per candidate
    !! parameter) and dstats (the diagnosis) of api_diagnose_nominal.
    character(len=*), parameter :: FIT_STAT_NAMES(8) = [character(len=10) :: 'chi2', &
        'chi2_prior', 'cond', 'dof', 'rank', 'iterations', 'converged', 'nlog']
    character(len=*), parameter :: CSTAT_NAMES(18) = [character(len=16) :: 'state', &
        'score_drop', 'score_p', 'score_dof', 'physical', 'identifiable', 'refit_done', &
        'refit_ok', 'lr_drop', 'lr_p', 'significant', 'acceptable', 'rival', 'separation', &
        'sep_experiment', 'sep_quantity', 'refit_chi2', 'refit_chi2_prior']
    character(len=*), parameter :: PSTAT_NAMES(6) = [character(len=12) :: 'estimate', &
        'sigma', 'active', 'refit_value', 'refit_sigma', 'refit_flag']
    character(len=*), parameter :: DSTAT_NAMES(6) = [character(len=16) :: 'verdict', &
        'ntested', 'alpha_each', 'base_chi2', 'base_chi2_prior', 'base_dof']
    !> mstats of the mesh test (beamid_api_dyndiag api_problem_diagnose)
    character(len=*), parameter :: MSTAT_NAMES(10) = [character(len=17) :: 'done', 'ok', &
        'elements_per_beam', 'recommended', 'chi2', 'drop', 'p_value', 'max_change', &
        'max_row', 'significant']

contains

    subroutine make_experiments(nbeams, nexp, exp_kind, exp_values, nrow, row_exp, row_q, &
                                tol, model, stat)
        integer(c_int), intent(in) :: nbeams, nexp, nrow
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        real(c_double), intent(in) :: exp_values(4, nexp), tol
        type(static_experiments_t), intent(out) :: model
        type(status_t), intent(inout) :: stat
        type(static_load_t), allocatable :: loads(:)
        integer :: e
        allocate (loads(nexp))
        do e = 1, nexp
            loads(e)%kind = int(exp_kind(e))
            loads(e)%fx = exp_values(1, e)
            loads(e)%fy = exp_values(2, e)
            loads(e)%moment = exp_values(3, e)
            loads(e)%wire_length = exp_values(4, e)
        end do
        call static_experiments_init(int(nbeams), loads, int(row_exp), int(row_q), &
                                     real(tol, dp), model, stat)
    end subroutine make_experiments

    !> The inverse problem (beamid_inverse) of static experiments given as
    !! (kind, fx, fy, moment, wire_length) columns: rows at t = 0.
    subroutine static_problem(nbeams, nexp, exp_kind, exp_values, nrow, row_exp, row_q, tol, &
                              model, stat)
        integer(c_int), intent(in) :: nbeams, nexp, nrow
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        real(c_double), intent(in) :: exp_values(4, nexp), tol
        type(inverse_problem_t), intent(out) :: model
        type(status_t), intent(inout) :: stat
        real(dp), allocatable :: values(:, :), t(:)
        allocate (values(NEXPVAL, nexp), t(nrow))
        values = 0.0_dp
        values(1:4, :) = exp_values
        t = 0.0_dp
        call inverse_problem_init(int(nbeams), int(exp_kind), values, int(row_exp), t, &
                                  int(row_q), real(tol, dp), model, stat)
    end subroutine static_problem

    subroutine make_options(max_iter, tol_step, tol_cost, opts)
        integer(c_int), intent(in) :: max_iter
        real(c_double), intent(in) :: tol_step, tol_cost
        type(fit_options_t), intent(out) :: opts
        if (max_iter > 0) opts%max_iter = int(max_iter)
        if (tol_step > 0.0_c_double) opts%tol_step = tol_step
        if (tol_cost > 0.0_c_double) opts%tol_cost = tol_cost
    end subroutine make_options

    !> Lower and upper physical bounds of every parameter.
    subroutine api_static_bounds(nbeams, nparams, lower, upper)
        integer(c_int), intent(in) :: nbeams, nparams
        real(c_double), intent(out) :: lower(nparams), upper(nparams)
        real(dp), allocatable :: lo(:), up(:)
        call static_bounds(int(nbeams), lo, up)
        lower = 0.0_c_double
        upper = 0.0_c_double
        if (size(lo) /= nparams) return
        lower = lo
        upper = up
    end subroutine api_static_bounds

    !> Residual structure tests of compare (beamid_estimation residual_structure):
    !! out = runs, expected runs, runs z, runs p, slope, trend z, trend p.
    subroutine api_residual_structure(n, level, group, normalized, out)
        integer(c_int), intent(in) :: n
        real(c_double), intent(in) :: level(n), normalized(n)
        integer(c_int), intent(in) :: group(n)
        real(c_double), intent(out) :: out(7)
        real(dp) :: o(7)
        call residual_structure(real(level, dp), int(group), real(normalized, dp), o)
        out = o
    end subroutine api_residual_structure

    !> The words of a code table of beamid_estimation, one per code from 0
    !! up, separated by ';': table 1 parameter flags (FLAG_*), 2 how a fit
    !! ended (STOP_*), 3 refit starts (START_*), 4 candidate states (CAND_*),
    !! and the column names of the result arrays: 5 a fit's stats, 6 cstats,
    !! 7 pstats, 8 dstats, 9 mstats of the mesh test (from position 1). code = -1 for an unknown table.
    subroutine api_code_names(table, names, code)
        integer(c_int), intent(in) :: table
        character(len=1024), intent(out) :: names
        integer(c_int), intent(out) :: code
        code = 0
        select case (table)
        case (1)
            names = joined(FLAG_NAMES)
        case (2)
            names = joined(STOP_NAMES)
        case (3)
            names = joined(START_NAMES)
        case (4)
            names = joined(CAND_NAMES)
        case (5)
            names = joined(FIT_STAT_NAMES)
        case (6)
            names = joined(CSTAT_NAMES)
        case (7)
            names = joined(PSTAT_NAMES)
        case (8)
            names = joined(DSTAT_NAMES)
        case (9)
            names = joined(MSTAT_NAMES)
        case default
            names = ''
            code = -1
        end select
    contains
        pure function joined(words) result(text)
            character(len=*), intent(in) :: words(:)
            character(len=:), allocatable :: text
            integer :: i
            text = trim(words(1))
            do i = 2, size(words)
                text = text//';'//trim(words(i))
            end do
        end function joined
    end subroutine api_code_names

    !> Chi-square survival function (for tests and Python-side reports).
    subroutine api_chi2_sf(x, k, p)
        real(c_double), intent(in) :: x
        integer(c_int), intent(in) :: k
        real(c_double), intent(out) :: p
        p = chi2_sf(real(x, dp), int(k))
    end subroutine api_chi2_sf

    !> Predictions of the data rows and their derivatives w.r.t. params(wrt).
    subroutine api_static_predict(nbeams, nparams, params, nexp, exp_kind, exp_values, nrow, &
                                  row_exp, row_q, nwrt, wrt, tol, pred, jac, code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nexp, nrow, nwrt
        real(c_double), intent(in) :: params(nparams), exp_values(4, nexp), tol
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow), wrt(nwrt)
        real(c_double), intent(out) :: pred(nrow), jac(nrow, nwrt)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(static_experiments_t) :: model
        type(status_t) :: stat
        real(dp) :: p(nrow), j(nrow, nwrt)
        pred = 0.0_c_double
        jac = 0.0_c_double
        call make_experiments(nbeams, nexp, exp_kind, exp_values, nrow, row_exp, row_q, tol, &
                              model, stat)
        if (stat%code == STATUS_OK) call model%evaluate(real(params, dp), int(wrt), p, j, stat)
        call status_out(stat, code, message)
        if (stat%code /= STATUS_OK) return
        pred = p
        jac = j
    end subroutine api_static_predict

    !> Weighted Gauss-Newton / LM fit (Eq. 39, 53-55, 142-145).
    !! stats = chi2, chi2_prior, cond, dof, rank, iterations, converged, nlog.
    !! The log arrays hold nlog + 1 entries (entry 1 = start).
    subroutine api_fit(nbeams, nparams, params0, nfree, free_idx, nprior, prior_idx, &
                       prior_mean, &
                       prior_sigma, nexp, exp_kind, exp_values, nrow, row_exp, row_q, &
                       row_value, row_sigma, tol, max_iter, tol_step, tol_cost, params, &
                       sigmas, cov, corr, flags, predictions, normalized, stats, log_cost, &
                       log_lambda, log_step, log_params, code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nfree, nprior, nexp, nrow, max_iter
        real(c_double), intent(in) :: params0(nparams)
        !> a priori arrays carry one unused trailing entry (f2py cannot pass empty arrays)
        real(c_double), intent(in) :: prior_mean(nprior + 1), prior_sigma(nprior + 1)
        integer(c_int), intent(in) :: free_idx(nfree), prior_idx(nprior + 1)
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        real(c_double), intent(in) :: exp_values(4, nexp), row_value(nrow), row_sigma(nrow)
        real(c_double), intent(in) :: tol, tol_step, tol_cost
        real(c_double), intent(out) :: params(nparams), sigmas(nfree), cov(nfree, nfree)
        real(c_double), intent(out) :: corr(nfree, nfree), predictions(nrow), normalized(nrow)
        integer(c_int), intent(out) :: flags(nfree)
        real(c_double), intent(out) :: stats(8)
        real(c_double), intent(out) :: log_cost(max_iter + 1), log_lambda(max_iter + 1)
        real(c_double), intent(out) :: log_step(max_iter + 1), log_params(nfree, max_iter + 1)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(static_experiments_t) :: model
        type(status_t) :: stat
        type(fit_options_t) :: opts
        type(fit_result_t) :: res
        type(prior_t) :: prior
        real(dp), allocatable :: lower(:), upper(:)

        params = params0
        sigmas = 0.0_c_double
        cov = 0.0_c_double
        corr = 0.0_c_double
        flags = 0
        predictions = 0.0_c_double
        normalized = 0.0_c_double
        stats = 0.0_c_double
        log_cost = 0.0_c_double
        log_lambda = 0.0_c_double
        log_step = 0.0_c_double
        log_params = 0.0_c_double
        call make_experiments(nbeams, nexp, exp_kind, exp_values, nrow, row_exp, row_q, tol, &
                              model, stat)
        if (stat%code == STATUS_OK) then
            call make_options(max_iter, tol_step, tol_cost, opts)
            prior%index = int(prior_idx(1:nprior))
            prior%mean = real(prior_mean(1:nprior), dp)
            prior%sigma = real(prior_sigma(1:nprior), dp)
            call static_bounds(int(nbeams), lower, upper)
            call fit_least_squares(model, real(row_value, dp), real(row_sigma, dp), &
                                   real(params0, dp), int(free_idx), lower, upper, prior, opts, &
                                   res, stat)
        end if
        call status_out(stat, code, message)
        if (stat%code == STATUS_OK .and. allocated(res%note)) message = res%note
        if (.not. allocated(res%params)) return
        if (stat%code /= STATUS_OK .and. stat%code /= ERR_NO_CONVERGENCE) return
        call copy_fit(res, params, sigmas, cov, corr, flags, predictions, normalized, stats, &
                      log_cost, log_lambda, log_step, log_params)
    end subroutine api_fit

    !> The outputs of api_fit from a fit result (stats and log layout there).
    subroutine copy_fit(res, params, sigmas, cov, corr, flags, predictions, normalized, stats, &
                        log_cost, log_lambda, log_step, log_params)
        type(fit_result_t), intent(in) :: res
        real(c_double), intent(out) :: params(:), sigmas(:), cov(:, :), corr(:, :)
        integer(c_int), intent(out) :: flags(:)
        real(c_double), intent(out) :: predictions(:), normalized(:), stats(8)
        real(c_double), intent(out) :: log_cost(:), log_lambda(:), log_step(:), log_params(:, :)
        integer :: n, lo
        params = res%params
        sigmas = res%sigmas
        cov = res%cov
        corr = res%corr
        flags = int(res%flags, c_int)
        predictions = res%predictions
        normalized = res%normalized
        stats = [res%chi2, res%chi2_prior, res%cond, real(res%dof, dp), real(res%rank, dp), &
                 real(res%iterations, dp), merge(1.0_dp, 0.0_dp, res%converged), &
                 real(res%nlog, dp)]
        log_cost = 0.0_c_double
        log_lambda = 0.0_c_double
        log_step = 0.0_c_double
        log_params = 0.0_c_double
        n = min(res%nlog + 1, size(log_cost))
        ! the log runs 0:nlog; its shrink in fit_least_squares reallocates (to 1-based
        ! bounds) only when the fit stopped before max_iter, so index from lbound
        lo = lbound(res%log_cost, 1)
        log_cost(1:n) = res%log_cost(lo:lo + n - 1)
        log_lambda(1:n) = res%log_lambda(lo:lo + n - 1)
        log_step(1:n) = res%log_step(lo:lo + n - 1)
        lo = lbound(res%log_params, 2)
        log_params(:, 1:n) = res%log_params(:, lo:lo + n - 1)
    end subroutine copy_fit

    !> Fit, or add an effect to a fit (beamid.fit, beamid.add_effect).
    !! nblock = 0: as api_fit from params0, plus how it ended: info(1) = stop
    !! (beamid_estimation STOP_*), info(2) = 0; note = what happened when it
    !! did not converge (flagged parameters), else ''.
    !! nblock > 0: params0 holds the estimates of a fit of free_idx (evaluated
    !! there, not refitted); the effect's parameters block(1:nblock), at their
    !! null values, are score-tested and freed, and the refit starts from the
    !! first-order estimate, from `nominal` (the user's starting values) with
    !! the effect at null, and by continuation in the effect's strength
    !! (refit_effect; start_mask limits the starts), keeping the best that
    !! converges. The outputs are those
    !! of the fit of [free_idx, block]; info(2) = the start kept (START_*),
    !! note = what every start gave. No start converging is ERR_NO_CONVERGENCE
    !! with the notes (and the best attempt in the outputs).
    subroutine api_fit_effect(nbeams, nparams, params0, nfree, free_idx, nblock, block, &
                              nominal, nprior, prior_idx, prior_mean, prior_sigma, nexp, &
                              exp_kind, exp_values, nrow, row_exp, row_q, row_value, row_sigma, &
                              tol, max_iter, start_mask, params, sigmas, cov, corr, flags, &
                              predictions, normalized, stats, log_cost, log_lambda, log_step, &
                              log_params, info, code, message, note)
        integer(c_int), intent(in) :: nbeams, nparams, nfree, nblock, nprior, nexp, nrow
        integer(c_int), intent(in) :: max_iter
        !> which refit starts to try, bits 1, 2, 4 = START_SCORE, START_NOMINAL,
        !! START_CONTINUATION (0: all)
        integer(c_int), intent(in) :: start_mask
        real(c_double), intent(in) :: params0(nparams), nominal(nparams)
        integer(c_int), intent(in) :: free_idx(nfree), block(nblock + 1)
        real(c_double), intent(in) :: prior_mean(nprior + 1), prior_sigma(nprior + 1)
        integer(c_int), intent(in) :: prior_idx(nprior + 1)
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        real(c_double), intent(in) :: exp_values(4, nexp), row_value(nrow), row_sigma(nrow)
        real(c_double), intent(in) :: tol
        real(c_double), intent(out) :: params(nparams), sigmas(nfree + nblock)
        real(c_double), intent(out) :: cov(nfree + nblock, nfree + nblock)
        real(c_double), intent(out) :: corr(nfree + nblock, nfree + nblock)
        real(c_double), intent(out) :: predictions(nrow), normalized(nrow), stats(8)
        integer(c_int), intent(out) :: flags(nfree + nblock), info(2)
        real(c_double), intent(out) :: log_cost(max_iter + 1), log_lambda(max_iter + 1)
        real(c_double), intent(out) :: log_step(max_iter + 1)
        real(c_double), intent(out) :: log_params(nfree + nblock, max_iter + 1)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        character(len=8192), intent(out) :: note
        type(static_experiments_t) :: model
        type(status_t) :: stat
        type(fit_options_t) :: opts
        type(fit_result_t) :: base, res
        type(score_result_t) :: score
        type(refit_info_t) :: rinfo
        type(prior_t) :: prior
        real(dp), allocatable :: lower(:), upper(:), nulls(:), y(:), sig(:)
        integer, allocatable :: blk(:)
        integer :: k

        params = params0
        sigmas = 0.0_c_double
        cov = 0.0_c_double
        corr = 0.0_c_double
        flags = 0
        predictions = 0.0_c_double
        normalized = 0.0_c_double
        stats = 0.0_c_double
        log_cost = 0.0_c_double
        log_lambda = 0.0_c_double
        log_step = 0.0_c_double
        log_params = 0.0_c_double
        info = 0
        note = ''
        call make_experiments(nbeams, nexp, exp_kind, exp_values, nrow, row_exp, row_q, tol, &
                              model, stat)
        if (stat%code == STATUS_OK) then
            call make_options(max_iter, 0.0_c_double, 0.0_c_double, opts)
            prior%index = int(prior_idx(1:nprior))
            prior%mean = real(prior_mean(1:nprior), dp)
            prior%sigma = real(prior_sigma(1:nprior), dp)
            call static_bounds(int(nbeams), lower, upper)
            call static_null_values(int(nbeams), nulls)
            y = real(row_value, dp)
            sig = real(row_sigma, dp)
            blk = int(block(1:nblock))
            if (nblock == 0) then
                call fit_least_squares(model, y, sig, real(params0, dp), int(free_idx), lower, &
                                       upper, prior, opts, res, stat)
            else
                if (any(blk < 1 .or. blk > nparams)) then
                    call set_status(stat, ERR_INPUT, 'add effect', 'effect parameter index '// &
                                    'outside 1..nparams')
                end if
                if (stat%code == STATUS_OK) call fit_at(model, y, sig, real(params0, dp), &
                    int(free_idx), lower, upper, prior, opts, base, stat)
                if (stat%code == STATUS_OK) call score_test(model, y, sig, base%params, &
                    base%free, lower, upper, prior, blk, opts, score, stat)
                if (stat%code == STATUS_OK) then
                    call refit_effect(model, y, sig, base, blk, score, real(nominal, dp), nulls, &
                                      lower, upper, prior, opts, res, rinfo, stat, &
                                      use=[(start_mask == 0 .or. btest(start_mask, k), k=0, 2)])
                    info(2) = int(rinfo%start, c_int)
                    note = rinfo%note
                end if
            end if
        end if
        call status_out(stat, code, message)
        if (.not. allocated(res%params)) return
        info(1) = int(res%stop, c_int)
        if (nblock == 0 .and. allocated(res%note)) note = res%note
        if (stat%code == STATUS_OK .and. allocated(res%note) .and. nblock == 0) message = res%note
        if (stat%code /= STATUS_OK .and. stat%code /= ERR_NO_CONVERGENCE) return
        call copy_fit(res, params, sigmas, cov, corr, flags, predictions, normalized, stats, &
                      log_cost, log_lambda, log_step, log_params)
    end subroutine api_fit_effect

    !> Diagnose a fit of static experiments (fits with releases: the one
    !! binding of the dynamic diagnosis, beamid_api_dyndiag
    !! api_problem_diagnose): the base fit is evaluated at `params0` (the
    !! estimates; not refitted), then every candidate block
    !! cand_params(cand_start(c):cand_start(c+1)-1) is score-tested and the
    !! leading ones refitted (beamid_estimation::diagnose, from the
    !! first-order estimate, from the user's starting values `nominal` and by
    !! continuation). Result columns by name: api_code_names tables 6-8
    !! (cstats 18 values per candidate, pstats 6 per candidate parameter,
    !! dstats 6). For every candidate the start its refit kept
    !! (refit_start, START_* of beamid_estimation, 0 when none converged or
    !! no refit was made) and what the refit starts gave: `notes` holds one
    !! line per candidate (newline-separated, empty without a refit).
    subroutine api_diagnose_nominal(nbeams, nparams, params0, nominal, nfree, free_idx, nprior, &
                                    prior_idx, prior_mean, prior_sigma, nexp, exp_kind, &
                                    exp_values, nrow, row_exp, row_q, row_value, row_sigma, tol, &
                                    max_iter, ncand, cand_start, ncandp, cand_params, alpha, &
                                    nrefit, ambiguity_delta, collinear, cstats, pstats, &
                                    refit_params, ranking, cosine, dstats, refit_start, notes, &
                                    code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nfree, nprior, nexp, nrow, max_iter
        real(c_double), intent(in) :: params0(nparams), nominal(nparams)
        real(c_double), intent(in) :: prior_mean(nprior + 1), prior_sigma(nprior + 1)
        integer(c_int), intent(in) :: free_idx(nfree), prior_idx(nprior + 1)
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        real(c_double), intent(in) :: exp_values(4, nexp), row_value(nrow), row_sigma(nrow)
        real(c_double), intent(in) :: tol
        integer(c_int), intent(in) :: ncand, ncandp, nrefit
        integer(c_int), intent(in) :: cand_start(ncand + 1), cand_params(ncandp + 1)
        real(c_double), intent(in) :: alpha, ambiguity_delta, collinear
        real(c_double), intent(out) :: cstats(18, ncand), pstats(6, ncandp + 1)
        real(c_double), intent(out) :: refit_params(nparams, ncand), cosine(ncand, ncand)
        integer(c_int), intent(out) :: ranking(ncand), refit_start(ncand)
        real(c_double), intent(out) :: dstats(6)
        character(len=8192), intent(out) :: notes
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(inverse_problem_t) :: model
        type(status_t) :: stat
        call static_problem(nbeams, nexp, exp_kind, exp_values, nrow, row_exp, row_q, tol, &
                            model, stat)
        call diagnose_core(model, stat, nbeams, nparams, params0, nominal, nfree, free_idx, nprior, &
                           prior_idx, prior_mean, prior_sigma, nexp, exp_kind, exp_values, nrow, &
                           row_exp, row_q, row_value, row_sigma, tol, max_iter, 0.0_c_double, &
                           0.0_c_double, ncand, cand_start, ncandp, cand_params, alpha, nrefit, &
                           ambiguity_delta, collinear, cstats, pstats, refit_params, ranking, &
                           cosine, dstats, refit_start, notes, code, message)
    end subroutine api_diagnose_nominal

    subroutine diagnose_core(model, stat, nbeams, nparams, params0, nominal, nfree, free_idx, nprior, &
                             prior_idx, prior_mean, prior_sigma, nexp, exp_kind, exp_values, &
                             nrow, row_exp, row_q, row_value, row_sigma, tol, max_iter, &
                             tol_step, tol_cost, ncand, cand_start, ncandp, cand_params, alpha, &
                             nrefit, ambiguity_delta, collinear, cstats, pstats, refit_params, &
                             ranking, cosine, dstats, refit_start, notes, code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nfree, nprior, nexp, nrow, max_iter
        real(c_double), intent(in) :: params0(nparams), nominal(nparams)
        real(c_double), intent(in) :: prior_mean(nprior + 1), prior_sigma(nprior + 1)
        integer(c_int), intent(in) :: free_idx(nfree), prior_idx(nprior + 1)
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        real(c_double), intent(in) :: exp_values(:, :), row_value(nrow), row_sigma(nrow)
        real(c_double), intent(in) :: tol, tol_step, tol_cost
        integer(c_int), intent(in) :: ncand, ncandp, nrefit
        integer(c_int), intent(in) :: cand_start(ncand + 1), cand_params(ncandp + 1)
        real(c_double), intent(in) :: alpha, ambiguity_delta, collinear
        real(c_double), intent(out) :: cstats(18, ncand), pstats(6, ncandp + 1)
        real(c_double), intent(out) :: refit_params(nparams, ncand), cosine(ncand, ncand)
        integer(c_int), intent(out) :: ranking(ncand), refit_start(ncand)
        real(c_double), intent(out) :: dstats(6)
        character(len=8192), intent(out) :: notes
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        !> the problem (built by the caller; stat: how that went)
        type(inverse_problem_t), intent(inout) :: model
        type(status_t), intent(inout) :: stat
        type(fit_options_t) :: opts
        type(diagnose_options_t) :: dopts
        type(fit_result_t) :: base
        type(prior_t) :: prior
        type(diagnosis_t) :: diag
        type(candidate_t), allocatable :: cands(:)
        integer, allocatable :: pexp(:), pq(:)
        character(len=:), allocatable :: text
        integer :: c, k, j, nf, r

        cstats = 0.0_c_double
        pstats = 0.0_c_double
        refit_params = 0.0_c_double
        cosine = 0.0_c_double
        ranking = 0
        refit_start = 0
        dstats = 0.0_c_double
        notes = ''
        if (stat%code == STATUS_OK) then
            call make_options(max_iter, tol_step, tol_cost, opts)
            prior%index = int(prior_idx(1:nprior))
            prior%mean = real(prior_mean(1:nprior), dp)
            prior%sigma = real(prior_sigma(1:nprior), dp)
            allocate (cands(ncand))
            do c = 1, ncand
                cands(c)%name = 'candidate'
                cands(c)%params = int(cand_params(cand_start(c):cand_start(c + 1) - 1))
            end do
            dopts%alpha = alpha
            dopts%nrefit = int(nrefit)
            dopts%ambiguity_delta = ambiguity_delta
            dopts%collinear = collinear
            call inverse_diagnose(model, real(row_value, dp), real(row_sigma, dp), &
                                  real(params0, dp), real(nominal, dp), int(free_idx), prior, &
                                  cands, opts, dopts, base, diag, pexp, pq, stat)
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
                    if (allocated(cr%score%estimate)) then
                        pstats(1:3, k) = [cr%score%estimate(j), cr%score%sigma(j), &
                                          b2r(cr%score%active(j))]
                    end if
                    if (cr%refit_ok) then
                        pstats(4:6, k) = [cr%refit%params(cands(c)%params(j)), &
                                          cr%refit%sigmas(nf + j), real(cr%refit%flags(nf + j), dp)]
                    end if
                end do
            end associate
        end do
        notes = text
        ranking = int(diag%ranking, c_int)
        cosine = diag%cosine
        dstats = [real(diag%verdict, dp), real(diag%ntested, dp), diag%alpha_each, base%chi2, &
                  base%chi2_prior, real(base%dof, dp)]
    contains
        pure real(dp) function b2r(flag)
            logical, intent(in) :: flag
            b2r = merge(1.0_dp, 0.0_dp, flag)
        end function b2r
    end subroutine diagnose_core

    !> The experiments of an estimation deck in beamid_inverse's layout
    !! (kind 1 tip, 2 wire, 3 release; exp_values(:, e) EV_*), nexp of them
    !! (sizes first: call with nexp = 0 to get the count in `count`).
    subroutine api_deck_experiments(path, nexp, exp_kind, exp_values, count, code, message)
        character(len=*), intent(in) :: path
        integer(c_int), intent(in) :: nexp
        integer(c_int), intent(out) :: exp_kind(nexp + 1), count, code
        real(c_double), intent(out) :: exp_values(12, nexp + 1)
        character(len=256), intent(out) :: message
        type(deck_t) :: d
        type(status_t) :: stat
        integer :: e
        exp_kind = 0
        exp_values = 0.0_c_double
        count = 0
        call read_deck(path, d, stat)
        call status_out(stat, code, message)
        if (stat%code /= STATUS_OK .or. .not. allocated(d%experiments)) return
        count = int(size(d%experiments), c_int)
        do e = 1, min(int(nexp), size(d%experiments))
            exp_kind(e) = int(d%experiments(e)%kind, c_int)
            exp_values(1:4, e) = [d%experiments(e)%fx, d%experiments(e)%fy, &
                                  d%experiments(e)%moment, d%experiments(e)%wire_length]
            if (allocated(d%exp_kind)) then
                if (d%exp_kind(e) > 0) then
                    exp_kind(e) = int(d%exp_kind(e), c_int)
                    exp_values(:, e) = d%exp_values(:, e)
                end if
            end if
        end do
    end subroutine api_deck_experiments

    !> Predictions of the data rows of any mix of experiment families
    !! (beamid_inverse: kinds 1 tip load, 2 wire, 3 release; exp_values(:, e)
    !! in the EV_* layout, 12 rows) and their derivatives w.r.t.
    !! params(wrt(1:nwrt)) (wrt carries one unused trailing entry: nwrt may be 0).
    subroutine api_problem_predict(nbeams, nparams, params, nexp, exp_kind, exp_values, nrow, &
                                   row_exp, row_t, row_q, nwrt, wrt, tol, pred, jac, code, &
                                   message)
        integer(c_int), intent(in) :: nbeams, nparams, nexp, nrow, nwrt
        real(c_double), intent(in) :: params(nparams), exp_values(12, nexp), row_t(nrow), tol
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow), wrt(nwrt + 1)
        real(c_double), intent(out) :: pred(nrow), jac(nrow, nwrt + 1)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(inverse_problem_t) :: model
        type(status_t) :: stat
        real(dp) :: p(nrow), j(nrow, nwrt)
        pred = 0.0_c_double
        jac = 0.0_c_double
        call inverse_problem_init(int(nbeams), int(exp_kind), real(exp_values, dp), &
                                  int(row_exp), real(row_t, dp), int(row_q), real(tol, dp), &
                                  model, stat)
        if (stat%code == STATUS_OK) call model%evaluate(real(params, dp), int(wrt(1:nwrt)), p, &
                                                        j, stat)
        call status_out(stat, code, message)
        if (stat%code /= STATUS_OK) return
        pred = p
        jac(:, 1:nwrt) = j
    end subroutine api_problem_predict

    !> api_fit_effect (nblock = 0) on any mix of experiment families, with
    !! a priori information either independent (use_cov = 0: mean, sigma) or
    !! a full covariance prior_cov of the prior parameters (use_cov = 1: a
    !! previous fit carried forward, Eq. 146-148, 164-166).
    subroutine api_problem_fit(nbeams, nparams, params0, nfree, free_idx, nprior, prior_idx, &
                               prior_mean, prior_sigma, use_cov, prior_cov, nexp, exp_kind, &
                               exp_values, nrow, row_exp, row_t, row_q, row_value, row_sigma, &
                               tol, max_iter, params, sigmas, cov, corr, flags, predictions, &
                               normalized, stats, log_cost, log_lambda, log_step, log_params, &
                               info, code, message, note)
        integer(c_int), intent(in) :: nbeams, nparams, nfree, nprior, nexp, nrow, max_iter
        integer(c_int), intent(in) :: use_cov
        real(c_double), intent(in) :: params0(nparams)
        real(c_double), intent(in) :: prior_mean(nprior + 1), prior_sigma(nprior + 1)
        real(c_double), intent(in) :: prior_cov(nprior + 1, nprior + 1)
        integer(c_int), intent(in) :: free_idx(nfree), prior_idx(nprior + 1)
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        real(c_double), intent(in) :: exp_values(12, nexp), row_t(nrow), row_value(nrow)
        real(c_double), intent(in) :: row_sigma(nrow), tol
        real(c_double), intent(out) :: params(nparams), sigmas(nfree), cov(nfree, nfree)
        real(c_double), intent(out) :: corr(nfree, nfree), predictions(nrow), normalized(nrow)
        integer(c_int), intent(out) :: flags(nfree), info(2)
        real(c_double), intent(out) :: stats(8)
        real(c_double), intent(out) :: log_cost(max_iter + 1), log_lambda(max_iter + 1)
        real(c_double), intent(out) :: log_step(max_iter + 1), log_params(nfree, max_iter + 1)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        character(len=8192), intent(out) :: note
        type(inverse_problem_t) :: model
        type(status_t) :: stat
        type(fit_options_t) :: opts
        type(fit_result_t) :: res
        type(prior_t) :: prior
        real(dp), allocatable :: lower(:), upper(:)
        integer :: n

        params = params0
        sigmas = 0.0_c_double
        cov = 0.0_c_double
        corr = 0.0_c_double
        flags = 0
        predictions = 0.0_c_double
        normalized = 0.0_c_double
        stats = 0.0_c_double
        log_cost = 0.0_c_double
        log_lambda = 0.0_c_double
        log_step = 0.0_c_double
        log_params = 0.0_c_double
        info = 0
        note = ''
        n = int(nprior)
        call inverse_problem_init(int(nbeams), int(exp_kind), real(exp_values, dp), &
                                  int(row_exp), real(row_t, dp), int(row_q), real(tol, dp), &
                                  model, stat)
        if (stat%code == STATUS_OK) then
            call make_options(max_iter, 0.0_c_double, 0.0_c_double, opts)
            if (use_cov /= 0) then
                call prior_from_covariance(int(prior_idx(1:n)), real(prior_mean(1:n), dp), &
                                           real(prior_cov(1:n, 1:n), dp), prior, stat)
            else
                prior%index = int(prior_idx(1:n))
                prior%mean = real(prior_mean(1:n), dp)
                prior%sigma = real(prior_sigma(1:n), dp)
            end if
        end if
        if (stat%code == STATUS_OK) then
            call static_bounds(int(nbeams), lower, upper)
            call fit_least_squares(model, real(row_value, dp), real(row_sigma, dp), &
                                   real(params0, dp), int(free_idx), lower, upper, prior, opts, &
                                   res, stat)
        end if
        call status_out(stat, code, message)
        if (.not. allocated(res%params)) return
        info(1) = int(res%stop, c_int)
        if (allocated(res%note)) note = res%note
        if (stat%code == STATUS_OK .and. allocated(res%note)) message = res%note
        if (stat%code /= STATUS_OK .and. stat%code /= ERR_NO_CONVERGENCE) return
        call copy_fit(res, params, sigmas, cov, corr, flags, predictions, normalized, stats, &
                      log_cost, log_lambda, log_step, log_params)
    end subroutine api_problem_fit
end module beamid_api_estimation
