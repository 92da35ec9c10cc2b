!> f2py-facing API for estimation (beamid_estimation on the problems of
!! beamid_inverse: any mix of static and release experiments; the diagnosis
!! binding is beamid_api_dyndiag).
!!
!! A problem crosses as plain arrays: experiments (kind and NEXPVAL = 12
!! values per experiment, beamid_inverse's EV_* layout), data rows
!! (experiment index, t, quantity code, value, sigma), free parameter indices,
!! a priori index/mean/sigma (Eq. 142-145). Indices are 1-based. Status
!! codes follow beamid_status; logical results are 0/1 integers.
module beamid_api_estimation
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, status_out, STATUS_OK, ERR_NO_CONVERGENCE, ERR_INPUT, set_status
    use beamid_estimation, only: residual_structure, residual_model_t
    use beamid_estimation, only: fit_options_t, fit_result_t, prior_t, fit_least_squares, &
                                 chi2_sf, fit_at, score_test, score_result_t, refit_effect, &
                                 refit_info_t, FLAG_NAMES, STOP_NAMES, START_NAMES, CAND_NAMES
    use beamid_static_experiments, only: static_bounds
    use beamid_estimation, only: prior_from_covariance
    use beamid_deck, only: deck_t, read_deck
    use beamid_inverse, only: inverse_problem_t, inverse_problem_init
    use beamid_dyn_diagnosis, only: null_side_model_t, null_side_init
    implicit none
    private

    public :: api_chi2_sf, api_static_bounds
    public :: api_residual_structure, api_fit_effect, api_code_names
    public :: api_problem_predict, api_problem_fit, api_deck_experiments

    ! notes strings (refit notes of every candidate) are character(len=8192):
    ! f2py needs the length as a literal

    !> The names of the columns of the result arrays (exported by
    !! api_code_names, tables 5-8, so that no front decodes them by position):
    !! stats of a fit, cstats (per candidate), pstats (per candidate
    !! parameter) and dstats (the diagnosis) of beamid_api_dyndiag api_problem_diagnose.
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

    !> The outputs of a fit entry before the fit (zero; params are set by the caller).
    subroutine clear_fit(sigmas, cov, corr, flags, predictions, normalized, stats, log_cost, &
                         log_lambda, log_step, log_params)
        real(c_double), intent(out) :: sigmas(:), cov(:, :), corr(:, :), predictions(:)
        real(c_double), intent(out) :: normalized(:), stats(:), log_cost(:), log_lambda(:)
        real(c_double), intent(out) :: log_step(:), log_params(:, :)
        integer(c_int), intent(out) :: flags(:)
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
    end subroutine clear_fit

    !> The outputs of a fit entry from a fit result: stats = chi2, chi2_prior,
    !! cond, dof, rank, iterations, converged, nlog (names: api_code_names 5);
    !! the log arrays hold nlog + 1 entries (entry 1 = start).
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

    !> Add an effect to a fit (beamid.add_effect) of any mix of experiment
    !! families (beamid_inverse layout, as api_problem_fit): params0 holds the
    !! estimates of a fit of free_idx (evaluated there, not refitted); the
    !! effect's parameters block(1:nblock), at their null values, are
    !! score-tested and freed, and the refit starts from the first-order
    !! estimate, from `nominal` (the user's starting values) with the effect at
    !! null, and by continuation in the effect's strength (refit_effect;
    !! start_mask bits 1, 2, 4 = START_SCORE, START_NOMINAL,
    !! START_CONTINUATION, 0: all), keeping the best that converges. With
    !! release experiments the motor lag, compliances and rotary inertias get
    !! one-sided columns at null (beamid_dyn_diagnosis null_side_model_t). The
    !! outputs are those of the fit of [free_idx, block] (api_problem_fit's);
    !! info(2) = the start kept (START_*), note = what every start gave. No
    !! start converging is ERR_NO_CONVERGENCE with the notes (and the best
    !! attempt in the outputs).
    subroutine api_fit_effect(nbeams, nparams, params0, nfree, free_idx, nblock, block, &
                              nominal, nprior, prior_idx, prior_mean, prior_sigma, nexp, &
                              exp_kind, exp_values, nrow, row_exp, row_t, row_q, row_value, &
                              row_sigma, tol, max_iter, start_mask, params, sigmas, cov, corr, &
                              flags, predictions, normalized, stats, log_cost, log_lambda, &
                              log_step, log_params, info, code, message, note)
        integer(c_int), intent(in) :: nbeams, nparams, nfree, nblock, nprior, nexp, nrow
        integer(c_int), intent(in) :: max_iter, start_mask
        real(c_double), intent(in) :: params0(nparams), nominal(nparams)
        integer(c_int), intent(in) :: free_idx(nfree), block(nblock)
        real(c_double), intent(in) :: prior_mean(nprior + 1), prior_sigma(nprior + 1)
        integer(c_int), intent(in) :: prior_idx(nprior + 1)
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        real(c_double), intent(in) :: exp_values(12, nexp), row_t(nrow), row_value(nrow)
        real(c_double), intent(in) :: row_sigma(nrow), tol
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
        type(inverse_problem_t) :: model
        type(null_side_model_t) :: side
        type(status_t) :: stat
        type(fit_options_t) :: opts
        type(fit_result_t) :: res
        type(refit_info_t) :: rinfo
        type(prior_t) :: prior

        params = params0
        call clear_fit(sigmas, cov, corr, flags, predictions, normalized, stats, log_cost, &
                       log_lambda, log_step, log_params)
        info = 0
        note = ''
        if (nblock < 1 .or. any(block < 1 .or. block > nparams)) then
            call set_status(stat, ERR_INPUT, 'add effect', 'effect parameter indices '// &
                            'empty or outside 1..nparams')
        else
            call inverse_problem_init(int(nbeams), int(exp_kind), real(exp_values, dp), &
                                      int(row_exp), real(row_t, dp), int(row_q), &
                                      real(tol, dp), model, stat)
        end if
        if (stat%code == STATUS_OK) then
            call make_options(max_iter, 0.0_c_double, 0.0_c_double, opts)
            prior%index = int(prior_idx(1:nprior))
            prior%mean = real(prior_mean(1:nprior), dp)
            prior%sigma = real(prior_sigma(1:nprior), dp)
            if (model%has_dynamic) then
                call null_side_init(int(nbeams), model, side)
                call add_effect(side)
            else
                call add_effect(model)
            end if
        end if
        call status_out(stat, code, message)
        if (.not. allocated(res%params)) return
        info(1) = int(res%stop, c_int)
        if (stat%code /= STATUS_OK .and. stat%code /= ERR_NO_CONVERGENCE) return
        call copy_fit(res, params, sigmas, cov, corr, flags, predictions, normalized, stats, &
                      log_cost, log_lambda, log_step, log_params)
    contains
        !> fit_at, score_test, refit_effect on `m` (the problem, or its
        !! one-sided wrapper), with the problem's bounds and null values
        subroutine add_effect(m)
            class(residual_model_t), intent(inout) :: m
            type(fit_result_t) :: base
            type(score_result_t) :: score
            real(dp), allocatable :: y(:), sig(:)
            integer :: k
            y = real(row_value, dp)
            sig = real(row_sigma, dp)
            call fit_at(m, y, sig, real(params0, dp), int(free_idx), model%lower, model%upper, &
                        prior, opts, base, stat)
            if (stat%code == STATUS_OK) call score_test(m, y, sig, base%params, base%free, &
                model%lower, model%upper, prior, int(block), opts, score, stat)
            if (stat%code /= STATUS_OK) return
            call refit_effect(m, y, sig, base, int(block), score, real(nominal, dp), &
                              model%nulls, model%lower, model%upper, prior, opts, res, rinfo, &
                              stat, use=[(start_mask == 0 .or. btest(start_mask, k), k=0, 2)])
            info(2) = int(rinfo%start, c_int)
            if (allocated(rinfo%note)) note = rinfo%note
        end subroutine add_effect
    end subroutine api_fit_effect

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
        call clear_fit(sigmas, cov, corr, flags, predictions, normalized, stats, log_cost, &
                       log_lambda, log_step, log_params)
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
