!> f2py-facing API for estimation: fits, the diagnosis and the improve
!! ladder (beamid_estimation, beamid_ladder) on the problems of
!! beamid_inverse, any mix of static and release experiments.
!!
!! A problem crosses as plain arrays: experiments (a kind each, and named
!! specs as sparse triples kv_exp, kv_key, kv_value: experiment, key of the
!! core's key table api_spec_keys, value; a key not given takes its default;
!! no positional layout crosses), data rows
!! (experiment index, t, observation, value, sigma; the observation an
!! index into the observation list obs_kind, obs_beam, obs_s of
!! beamid_observations' kind codes and station loci), free parameter indices,
!! a priori information as prior(3, nprior), a column [parameter index, mean,
!! sigma] per parameter (Eq. 142-145). Indices are 1-based. Sizes are
!! implied by the arrays (f2py fills them in); no array carries padding. Status
!! codes follow beamid_status; logical results are 0/1 integers.
!! Outputs of a failed call are zeros: f2py allocates output arrays zeroed and
!! declares output scalars = 0 (characters blank), so no entry zeroes them.
!!
!! An improve ladder is a run the caller owns: api_ladder_open starts it in a
!! slot of the binding's handle table (beamid_api_runs) and returns its
!! handle; api_ladder_handle_step steps it (a rung per call: the front shows
!! progress), api_ladder_handle_rung, _fit, _rows and _diag return its rungs
!! (results of a size known only after the run), api_ladder_close frees it.
!! No ladder is held anywhere else: two ladders never meet.
module beamid_api_estimation
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, status_out, STATUS_OK, ERR_NO_CONVERGENCE, ERR_INPUT, &
                             set_status, fmt_int, put_text
    use beamid_estimation, only: residual_structure, residual_model_t
    use beamid_estimation, only: fit_options_t, fit_result_t, prior_t, fit_least_squares, &
                                 lsq_problem_t, diagnose_options_t, chi2_sf, fit_at, score_test, &
                                 score_result_t, refit_effect, refit_info_t, FLAG_NAMES, &
                                 STOP_NAMES, START_NAMES, CAND_NAMES
    use beamid_inverse, only: inverse_problem_t, chain_layout
    use beamid_problem, only: problem_from_arrays, problem_lsq_from_arrays, observation_list, &
                              specs_from_triples, experiment_spec_t
    use beamid_family, only: SPEC_KEYS
    use beamid_families, only: registered_families
    use beamid_family, only: family_slot_t
    use beamid_observations, only: observation_t
    use beamid_dyn_diagnosis, only: null_side_model_t, null_side_init, time_structure
    use beamid_chain_fit, only: chain_fit
    use beamid_dyn_diagnosis, only: mesh_check, mesh_test_t
    use beamid_dynamic_experiments, only: exp_histories_t
    use beamid_loads, only: TARGET_NAMES, HIST_NAMES
    use beamid_effects, only: EFFECTS, NEFFECTS, FAMILY_NAMES, NFAMILY, effect_params
    use beamid_ladder, only: problem_t, cand_set_t, diag_out_t, rung_t, problem_diagnose, &
                             ladder_t, ladder_start, ladder_step
    use beamid_api_marshal, only: copy_fit, copy_diag, rung_out, rung_fit_out, rung_diag_out, &
                                  rung_rows_out
    use beamid_replicates, only: fit_replicates, replicate_out_t, NREP_STATS
    use beamid_api_runs, only: runs, RUN_LADDER, run_open, run_close, runs_held, run_ok
    implicit none
    private

    public :: api_chi2_sf
    public :: api_residual_structure, api_fit_effect, api_code_names
    public :: api_effect_sizes, api_effect_table
    public :: api_problem_predict, api_chain_layout, api_fit_chain
    public :: api_problem_diagnose, api_time_structure, api_spec_keys
    public :: api_ladder_open, api_ladder_close, api_ladder_handles_open, api_ladder_handle_step
    public :: api_ladder_handle_rung, api_ladder_handle_fit, api_ladder_handle_diag, &
              api_ladder_handle_rows
    public :: api_mesh_check, api_fit_replicates, api_family_table

    ! notes strings (refit notes of every candidate) are character(len=8192):
    ! f2py needs the length as a literal

    !> The names of the columns of the result arrays (exported by
    !! api_code_names, tables 5-8, so that no front decodes them by position):
    !! stats of a fit, cstats (per candidate), pstats (per candidate
    !! parameter) and dstats (the diagnosis) of api_problem_diagnose.
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
    !> mstats of the mesh test (api_problem_diagnose)
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

    !> Residual structure tests of compare (beamid_estimation residual_structure):
    !! out = runs, expected runs, runs z, runs p, slope, trend z, trend p.
    subroutine api_residual_structure(n, level, group, normalized, out)
        integer(c_int), intent(in) :: n
        !f2py intent(hide) n
        real(c_double), intent(in) :: level(n), normalized(n)
        integer(c_int), intent(in) :: group(n)
        real(c_double), intent(out) :: out(7)
        call residual_structure(real(level, dp), int(group), real(normalized, dp), out)
    end subroutine api_residual_structure

    !> The words of a code table of beamid_estimation, one per code from 0
    !! up, separated by ';': table 1 parameter flags (FLAG_*), 2 how a fit
    !! ended (STOP_*), 3 refit starts (START_*), 4 candidate states (CAND_*),
    !! and the column names of the result arrays: 5 a fit's stats, 6 cstats,
    !! 7 pstats, 8 dstats, 9 mstats of the mesh test (from position 1); and
    !! the load histories of beamid_loads by code from 1: 10 the targets
    !! (TARGET_*), 11 the history kinds (HIST_*). code = -1 for an unknown
    !! table.
    subroutine api_code_names(table, names, code)
        integer(c_int), intent(in) :: table
        character(len=1024), intent(out) :: names
        integer(c_int), intent(out) :: code
        character(len=1024) :: tables(11)
        tables = [character(len=1024) :: joined(FLAG_NAMES), joined(STOP_NAMES), &
                  joined(START_NAMES), joined(CAND_NAMES), joined(FIT_STAT_NAMES), &
                  joined(CSTAT_NAMES), joined(PSTAT_NAMES), joined(DSTAT_NAMES), &
                  joined(MSTAT_NAMES), joined(TARGET_NAMES), joined(HIST_NAMES)]
        code = 0
        names = ''
        if (table >= 1 .and. table <= size(tables)) then
            names = tables(table)
        else
            code = -1
        end if
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

    !> Sizes of the effects table (api_effect_table) for a chain of nbeams
    !! beams: the number of effects and of their parameter indices in all.
    subroutine api_effect_sizes(nbeams, neffect, nindex)
        integer(c_int), intent(in) :: nbeams
        integer(c_int), intent(out) :: neffect, nindex
        integer :: i
        type(status_t) :: st
        integer, allocatable :: p(:)
        neffect = int(NEFFECTS, c_int)
        nindex = 0
        do i = 1, NEFFECTS
            call effect_params(max(int(nbeams), 1), EFFECTS(i)%name, p, st)
            nindex = nindex + int(size(p), c_int)
        end do
    end subroutine api_effect_sizes

    !> The effects table of beamid_effects for a chain of nbeams beams (the
    !! one definition the Python Effect list reads): `text` holds the family
    !! names on its first line, then per effect its name and description,
    !! separated by a tab; ranks(f, e) is effect e's place among family f's
    !! default candidates (0: f cannot see it); values(:, e) its null value,
    !! lower and upper bound; its parameter indices (1-based) are
    !! indices(starts(e):starts(e + 1) - 1). Sizes: api_effect_sizes.
    subroutine api_effect_table(nbeams, neffect, nindex, text, ranks, values, starts, &
                                indices, code, message)
        integer(c_int), intent(in) :: nbeams, neffect, nindex
        character(len=4096), intent(out) :: text
        ! ranks: one row per family of beamid_effects (NFAMILY = 3; f2py needs the number)
        integer(c_int), intent(out) :: ranks(3, neffect), starts(neffect + 1), indices(nindex)
        real(c_double), intent(out) :: values(3, neffect)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        character(len=:), allocatable :: t
        integer, allocatable :: p(:)
        type(status_t) :: st
        integer :: i, k
        integer(c_int) :: ne, ni
        call api_effect_sizes(nbeams, ne, ni)
        if (nbeams < 1 .or. neffect /= ne .or. nindex /= ni) then
            call set_status(st, ERR_INPUT, 'effects', 'nbeams = '//fmt_int(int(nbeams))// &
                            ', neffect = '//fmt_int(int(neffect))//', nindex = '// &
                            fmt_int(int(nindex))//', expected nbeams >= 1 and the sizes '// &
                            'of api_effect_sizes')
            call status_out(st, code, message)
            return
        end if
        t = trim(FAMILY_NAMES(1))
        do i = 2, NFAMILY
            t = t//achar(9)//trim(FAMILY_NAMES(i))
        end do
        k = 1
        do i = 1, NEFFECTS
            t = t//new_line('a')//trim(EFFECTS(i)%name)//achar(9)//trim(EFFECTS(i)%description)
            ranks(:, i) = int(EFFECTS(i)%rank, c_int)
            values(:, i) = real([EFFECTS(i)%null_value, EFFECTS(i)%lower, EFFECTS(i)%upper], &
                                c_double)
            call effect_params(int(nbeams), EFFECTS(i)%name, p, st)
            starts(i) = int(k, c_int)
            indices(k:k + size(p) - 1) = int(p, c_int)
            k = k + size(p)
        end do
        starts(NEFFECTS + 1) = int(k, c_int)
        call put_text(t, text)
        call status_out(st, code, message)
    end subroutine api_effect_table

    !> The key table of experiment specs (beamid_family SPEC_KEYS), one line
    !! per key: name, its identifier (EV_*, which is its number: its line), the
    !! families that accept it ('+'-joined names from the registry), its
    !! default and its meaning, tab-separated; then one line per experiment
    !! kind the families take: 'kind', its code, its family, its words. The
    !! fronts build experiments by these names (a key's number is its line).
    subroutine api_spec_keys(text, code, message)
        character(len=4096), intent(out) :: text
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        character(len=:), allocatable :: t, fams
        type(family_slot_t), allocatable :: reg(:)
        integer, allocatable :: codes(:)
        character(len=32) :: buf
        integer :: k, f
        call registered_families(reg)
        t = ''
        do k = 1, size(SPEC_KEYS)
            fams = ''
            do f = 1, size(reg)
                if (.not. reg(f)%item%accepts(k)) cycle
                if (len(fams) > 0) fams = fams//'+'
                fams = fams//reg(f)%item%name()
            end do
            write (buf, '(g0)') SPEC_KEYS(k)%default
            if (k > 1) t = t//new_line('a')
            t = t//trim(SPEC_KEYS(k)%name)//achar(9)//fmt_int(SPEC_KEYS(k)%key)//achar(9)// &
                fams//achar(9)//trim(buf)//achar(9)//trim(SPEC_KEYS(k)%about)
        end do
        do f = 1, size(reg)
            codes = reg(f)%item%kind_codes()
            do k = 1, size(codes)
                t = t//new_line('a')//'kind'//achar(9)//fmt_int(codes(k))//achar(9)// &
                    reg(f)%item%name()//achar(9)//reg(f)%item%kind_label(codes(k))
            end do
        end do
        call table_out(t, 'api_spec_keys', text, code, message)
    end subroutine api_spec_keys

    !> A table's text `t` into the binding's buffer `text`; a table longer
    !! than the buffer is an input error naming `what` (a table is never cut:
    !! the fronts parse it).
    subroutine table_out(t, what, text, code, message)
        character(len=*), intent(in) :: t, what
        character(len=*), intent(out) :: text
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(status_t) :: stat
        text = t
        if (len(t) > len(text)) call set_status(stat, ERR_INPUT, what, 'the table takes '// &
                                                fmt_int(len(t))//' characters, more than '// &
                                                'the '//fmt_int(len(text))//' the binding passes')
        call status_out(stat, code, message)
    end subroutine table_out

    !> Chi-square survival function (for tests and Python-side reports).
    subroutine api_chi2_sf(x, k, p)
        real(c_double), intent(in) :: x
        integer(c_int), intent(in) :: k
        real(c_double), intent(out) :: p
        p = chi2_sf(real(x, dp), int(k))
    end subroutine api_chi2_sf

    !> The one fit entry (beamid.fit, beamid.add_effect) on any mix of
    !! experiment families (beamid_inverse layout). A priori information is
    !! independent (prior_cov empty: prior's means and sigmas) or a full
    !! covariance of the prior parameters (prior_cov: nprior*nprior values,
    !! column by column; a previous fit carried forward, Eq. 146-148, 164-166).
    !! nblock = 0: weighted Gauss-Newton / LM fit of free_idx from params0
    !! (Eq. 39, 53-55, 142-145); info(1) = how it ended (STOP_*), note = what
    !! happened when it did not converge (flagged parameters).
    !! nblock > 0: params0 holds the estimates of a fit of free_idx (evaluated
    !! there, not refitted); the effect's parameters block(1:nblock), at their
    !! null values, are score-tested and freed, and the refit starts from the
    !! first-order estimate, from `nominal` (the user's starting values) with
    !! the effect at null, and by continuation in the effect's strength
    !! (refit_effect; start_mask bits 1, 2, 4 = START_SCORE, START_NOMINAL,
    !! START_CONTINUATION, 0: all), keeping the best that converges. With
    !! release experiments the motor lag, compliances and rotary inertias get
    !! one-sided columns at null (beamid_dyn_diagnosis null_side_model_t).
    !! The outputs are those of the fit of [free_idx, block] (copy_fit);
    !! info(2) = the start kept (START_*), note = what every start gave. No
    !! start converging is ERR_NO_CONVERGENCE with the notes (and the best
    !! attempt in the outputs).
    subroutine api_fit_effect(nbeams, nparams, params0, nfree, free_idx, nblock, block, &
                              nominal, nprior, prior, ncov, prior_cov, nexp, exp_kind, &
                              nkv, kv_exp, kv_key, kv_value, nrow, row_exp, row_t, row_q, nobs, obs_kind, &
                              obs_beam, obs_s, row_value, row_sigma, tol, nhs, hist_spec, &
                              nhtab, hist_tab, max_iter, start_mask, params, sigmas, cov, corr, &
                              flags, &
                              predictions, normalized, stats, log_cost, log_lambda, log_step, &
                              log_params, info, code, message, note)
        integer(c_int), intent(in) :: nhs, nhtab
        !f2py intent(hide) nhs, nhtab
        real(c_double), intent(in) :: hist_spec(10, nhs), hist_tab(2, nhtab)
        integer(c_int), intent(in) :: nbeams, nparams, nfree, nblock, nprior, nexp, nrow
        !f2py intent(hide) nparams, nfree, nblock, nprior, ncov, nexp, nrow
        integer(c_int), intent(in) :: max_iter, start_mask, ncov
        real(c_double), intent(in) :: params0(nparams), nominal(nparams)
        integer(c_int), intent(in) :: free_idx(nfree), block(nblock)
        real(c_double), intent(in) :: prior(3, nprior), prior_cov(ncov)
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        integer(c_int), intent(in) :: nobs
        !f2py intent(hide) nobs
        integer(c_int), intent(in) :: obs_kind(nobs), obs_beam(nobs)
        real(c_double), intent(in) :: obs_s(nobs)
        real(c_double), intent(in) :: row_t(nrow), row_value(nrow)
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
        integer(c_int), intent(in) :: nkv
        !f2py intent(hide) nkv
        integer(c_int), intent(in) :: kv_exp(nkv), kv_key(nkv)
        real(c_double), intent(in) :: kv_value(nkv)
        character(len=8192), intent(out) :: note
        type(inverse_problem_t) :: model
        type(null_side_model_t) :: side
        type(status_t) :: stat
        type(fit_options_t) :: opts
        type(fit_result_t) :: res
        type(refit_info_t) :: rinfo
        type(lsq_problem_t) :: lp

        params = params0
        note = ''
        if (any(block < 1 .or. block > nparams)) then
            call set_status(stat, ERR_INPUT, 'add effect', 'effect parameter index '// &
                            'outside 1..nparams')
        else
            call set_up(nbeams, exp_kind, kv_exp, kv_key, kv_value, row_exp, row_t, row_q, &
                        obs_kind, obs_beam, obs_s, tol, row_value, row_sigma, prior, &
                        prior_cov, hist_spec, hist_tab, model, lp, stat)
        end if
        call make_options(max_iter, 0.0_c_double, 0.0_c_double, opts)
        if (stat%code == STATUS_OK .and. nblock == 0) then
            call fit_least_squares(model, lp, real(params0, dp), int(free_idx), opts, res, stat)
            if (allocated(res%note)) note = res%note
        else if (stat%code == STATUS_OK .and. model%timed()) then
            call null_side_init(int(nbeams), model, side)
            call add_effect(side)
        else if (stat%code == STATUS_OK) then
            call add_effect(model)
        end if
        call status_out(stat, code, message)
        if (nblock == 0 .and. stat%code == STATUS_OK .and. allocated(res%note)) message = res%note
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
            integer :: k
            call fit_at(m, lp, real(params0, dp), int(free_idx), opts, base, stat)
            if (stat%code == STATUS_OK) call score_test(m, lp, base%params, base%free, &
                                                        int(block), opts, score, stat)
            if (stat%code /= STATUS_OK) return
            call refit_effect(m, lp, base, int(block), score, real(nominal, dp), opts, res, &
                              rinfo, stat, use=[(start_mask == 0 .or. btest(start_mask, k), &
                                                 k=0, 2)])
            info(2) = int(rinfo%start, c_int)
            if (allocated(rinfo%note)) note = rinfo%note
        end subroutine add_effect
    end subroutine api_fit_effect

    !> The fit with the measurement chain's row treatments (beamid_chain_fit:
    !! the experiments' losses, burn-in and estimated sigmas, EV_LOSS,
    !! EV_BURNIN, EV_SIGEST), results as api_fit_effect's (no effect block)
    !! and per row: the last weight, the sigma it was judged with, that
    !! sigma's standard deviation (0 where given) and 1 for a gross error.
    subroutine api_fit_chain(nbeams, nparams, params0, nfree, free_idx, nprior, prior, ncov, &
                             prior_cov, nexp, exp_kind, nkv, kv_exp, kv_key, kv_value, nrow, row_exp, row_t, &
                             row_q, nobs, obs_kind, obs_beam, obs_s, row_value, row_sigma, tol, &
                             nhs, hist_spec, nhtab, hist_tab, &
                             max_iter, params, sigmas, cov, &
                             corr, flags, predictions, normalized, stats, log_cost, log_lambda, &
                             log_step, log_params, info, weights, sigma_used, sigma_sd, &
                             flagged, code, message, note)
        integer(c_int), intent(in) :: nhs, nhtab
        !f2py intent(hide) nhs, nhtab
        real(c_double), intent(in) :: hist_spec(10, nhs), hist_tab(2, nhtab)
        integer(c_int), intent(in) :: nbeams, nparams, nfree, nprior, nexp, nrow, ncov
        !f2py intent(hide) nparams, nfree, nprior, ncov, nexp, nrow
        integer(c_int), intent(in) :: max_iter
        real(c_double), intent(in) :: params0(nparams)
        integer(c_int), intent(in) :: free_idx(nfree)
        real(c_double), intent(in) :: prior(3, nprior), prior_cov(ncov)
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        integer(c_int), intent(in) :: nobs
        !f2py intent(hide) nobs
        integer(c_int), intent(in) :: obs_kind(nobs), obs_beam(nobs)
        real(c_double), intent(in) :: obs_s(nobs)
        real(c_double), intent(in) :: row_t(nrow), row_value(nrow)
        real(c_double), intent(in) :: row_sigma(nrow), tol
        real(c_double), intent(out) :: params(nparams), sigmas(nfree)
        real(c_double), intent(out) :: cov(nfree, nfree), corr(nfree, nfree)
        real(c_double), intent(out) :: predictions(nrow), normalized(nrow), stats(8)
        integer(c_int), intent(out) :: flags(nfree), info(2)
        real(c_double), intent(out) :: log_cost(max_iter + 1), log_lambda(max_iter + 1)
        real(c_double), intent(out) :: log_step(max_iter + 1)
        real(c_double), intent(out) :: log_params(nfree, max_iter + 1)
        real(c_double), intent(out) :: weights(nrow), sigma_used(nrow), sigma_sd(nrow)
        integer(c_int), intent(out) :: flagged(nrow)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        integer(c_int), intent(in) :: nkv
        !f2py intent(hide) nkv
        integer(c_int), intent(in) :: kv_exp(nkv), kv_key(nkv)
        real(c_double), intent(in) :: kv_value(nkv)
        character(len=8192), intent(out) :: note
        type(inverse_problem_t) :: model
        type(status_t) :: stat
        type(fit_options_t) :: opts
        type(fit_result_t) :: res
        type(lsq_problem_t) :: lp
        real(dp) :: w(nrow), su(nrow), sd(nrow)
        logical :: fl(nrow)
        params = params0
        note = ''
        call set_up(nbeams, exp_kind, kv_exp, kv_key, kv_value, row_exp, row_t, row_q, &
                    obs_kind, obs_beam, obs_s, tol, row_value, row_sigma, prior, prior_cov, &
                    hist_spec, hist_tab, model, lp, stat)
        call make_options(max_iter, 0.0_c_double, 0.0_c_double, opts)
        if (stat%code == STATUS_OK) then
            call chain_fit(model, lp, real(params0, dp), int(free_idx), opts, model%rows, res, &
                           w, su, sd, fl, stat)
            if (allocated(res%note)) note = res%note
        end if
        call status_out(stat, code, message)
        if (stat%code == STATUS_OK .and. allocated(res%note)) message = res%note
        if (.not. allocated(res%params)) return
        info(1) = int(res%stop, c_int)
        if (stat%code /= STATUS_OK .and. stat%code /= ERR_NO_CONVERGENCE) return
        call copy_fit(res, params, sigmas, cov, corr, flags, predictions, normalized, stats, &
                      log_cost, log_lambda, log_step, log_params)
        weights = w
        sigma_used = su
        sigma_sd = sd
        flagged = merge(1_c_int, 0_c_int, fl)
    end subroutine api_fit_chain

    !> Predictions of the data rows of any mix of experiment families
    !! (beamid_problem: kinds 1 tip load, 2 wire, 3 release; their specs as
    !! triples, api_spec_keys) and their derivatives w.r.t.
    !! params(wrt) (wrt may be empty).
    subroutine api_problem_predict(nbeams, nparams, params, nexp, exp_kind, nkv, kv_exp, kv_key, kv_value, nrow, &
                                   row_exp, row_t, row_q, nobs, obs_kind, obs_beam, obs_s, &
                                   nwrt, wrt, tol, nhs, hist_spec, nhtab, hist_tab, pred, jac, code, message)
        integer(c_int), intent(in) :: nhs, nhtab
        !f2py intent(hide) nhs, nhtab
        real(c_double), intent(in) :: hist_spec(10, nhs), hist_tab(2, nhtab)
        integer(c_int), intent(in) :: nbeams, nparams, nexp, nrow, nwrt
        !f2py intent(hide) nparams, nexp, nrow, nwrt
        real(c_double), intent(in) :: params(nparams), row_t(nrow), tol
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow), wrt(nwrt)
        integer(c_int), intent(in) :: nobs
        !f2py intent(hide) nobs
        integer(c_int), intent(in) :: obs_kind(nobs), obs_beam(nobs)
        real(c_double), intent(in) :: obs_s(nobs)
        real(c_double), intent(out) :: pred(nrow), jac(nrow, nwrt)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        integer(c_int), intent(in) :: nkv
        !f2py intent(hide) nkv
        integer(c_int), intent(in) :: kv_exp(nkv), kv_key(nkv)
        real(c_double), intent(in) :: kv_value(nkv)
        type(inverse_problem_t) :: model
        type(status_t) :: stat
        real(dp) :: p(nrow), j(nrow, nwrt)
        call make_model(nbeams, exp_kind, kv_exp, kv_key, kv_value, row_exp, row_t, row_q, &
                        obs_kind, obs_beam, obs_s, tol, hist_spec, hist_tab, model, stat)
        if (stat%code == STATUS_OK) call model%evaluate(real(params, dp), int(wrt), p, j, stat)
        call status_out(stat, code, message)
        if (stat%code /= STATUS_OK) return
        pred = p
        jac = j
    end subroutine api_problem_predict

    !> The nuisance parameters of the measurement chain the experiments'
    !! specs ask for (beamid_inverse chain_layout), in parameter
    !! order after the model's: kind (1 clock offset, 2 bias, 3 scale, 4
    !! initial velocity), experiment (1-based) and entry of the problem's
    !! observation list of nobs entries (0 for a clock offset or an initial
    !! velocity); the first n of each (at most nexp (2 + 2 MAX_CHANNEL_BITS))
    !! are filled.
    subroutine api_chain_layout(nexp, exp_kind, nkv, kv_exp, kv_key, kv_value, nobs, n, kinds, exps, qs, code, &
                                message)
        integer(c_int), intent(in) :: nexp, nobs
        !f2py intent(hide) nexp
        integer(c_int), intent(in) :: exp_kind(nexp)
        integer(c_int), intent(out) :: n
        integer(c_int), intent(out) :: kinds(106*nexp), exps(106*nexp), qs(106*nexp)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        integer(c_int), intent(in) :: nkv
        !f2py intent(hide) nkv
        integer(c_int), intent(in) :: kv_exp(nkv), kv_key(nkv)
        real(c_double), intent(in) :: kv_value(nkv)
        type(experiment_spec_t), allocatable :: specs(:)
        type(status_t) :: stat
        integer, allocatable :: k(:), e(:), q(:)
        n = 0
        kinds = 0
        exps = 0
        qs = 0
        call make_specs(exp_kind, kv_exp, kv_key, kv_value, specs, stat)
        if (stat%code /= STATUS_OK) then
            call status_out(stat, code, message)
            return
        end if
        call chain_layout(int(exp_kind), specs, k, e, q, stat, int(nobs))
        call status_out(stat, code, message)
        if (stat%code /= STATUS_OK) return
        n = int(size(k), c_int)
        kinds(1:n) = int(k, c_int)
        exps(1:n) = int(e, c_int)
        qs(1:n) = int(q, c_int)
    end subroutine api_chain_layout

    !> The experiments' specs from the named triples the binding takes
    !! (experiment, key of the core's key table, value: beamid_problem
    !! specs_from_triples; the table is api_spec_keys).
    subroutine make_specs(exp_kind, kv_exp, kv_key, kv_value, specs, stat)
        integer(c_int), intent(in) :: exp_kind(:), kv_exp(:), kv_key(:)
        real(c_double), intent(in) :: kv_value(:)
        type(experiment_spec_t), allocatable, intent(out) :: specs(:)
        type(status_t), intent(inout) :: stat
        call specs_from_triples(int(exp_kind), int(kv_exp), int(kv_key), real(kv_value, dp), &
                                specs, stat)
    end subroutine make_specs

    !> The estimation entries' one set-up (beamid_problem
    !! problem_lsq_from_arrays) from the binding's arrays, the named specs
    !! made specs (make_specs) and the arrays in the library's kinds.
    subroutine set_up(nbeams, exp_kind, kv_exp, kv_key, kv_value, row_exp, row_t, row_q, &
                      obs_kind, obs_beam, obs_s, tol, row_value, row_sigma, prior, prior_cov, &
                      hist_spec, hist_tab, model, lp, stat)
        integer(c_int), intent(in) :: nbeams, exp_kind(:), kv_exp(:), kv_key(:), row_exp(:)
        integer(c_int), intent(in) :: row_q(:), obs_kind(:), obs_beam(:)
        real(c_double), intent(in) :: kv_value(:), row_t(:), obs_s(:), tol, row_value(:)
        real(c_double), intent(in) :: row_sigma(:), prior(:, :), prior_cov(:)
        real(c_double), intent(in) :: hist_spec(:, :), hist_tab(:, :)
        type(inverse_problem_t), intent(out) :: model
        type(lsq_problem_t), intent(out) :: lp
        type(status_t), intent(inout) :: stat
        type(experiment_spec_t), allocatable :: specs(:)
        call make_specs(exp_kind, kv_exp, kv_key, kv_value, specs, stat)
        if (stat%code /= STATUS_OK) return
        call problem_lsq_from_arrays(int(nbeams), int(exp_kind), specs, &
                                     int(row_exp), real(row_t, dp), int(row_q), int(obs_kind), &
                                     int(obs_beam), real(obs_s, dp), real(tol, dp), &
                                     real(row_value, dp), real(row_sigma, dp), &
                                     real(prior, dp), real(prior_cov, dp), model, lp, stat, &
                                     make_hist(hist_spec, hist_tab))
    end subroutine set_up

    !> The model of the prediction entries (beamid_problem
    !! problem_from_arrays) from the binding's arrays, as set_up.
    subroutine make_model(nbeams, exp_kind, kv_exp, kv_key, kv_value, row_exp, row_t, row_q, &
                          obs_kind, obs_beam, obs_s, tol, hist_spec, hist_tab, model, stat)
        integer(c_int), intent(in) :: nbeams, exp_kind(:), kv_exp(:), kv_key(:), row_exp(:)
        integer(c_int), intent(in) :: row_q(:), obs_kind(:), obs_beam(:)
        real(c_double), intent(in) :: kv_value(:), row_t(:), obs_s(:), tol
        real(c_double), intent(in) :: hist_spec(:, :), hist_tab(:, :)
        type(inverse_problem_t), intent(out) :: model
        type(status_t), intent(inout) :: stat
        type(experiment_spec_t), allocatable :: specs(:)
        call make_specs(exp_kind, kv_exp, kv_key, kv_value, specs, stat)
        if (stat%code /= STATUS_OK) return
        call problem_from_arrays(int(nbeams), int(exp_kind), specs, int(row_exp), &
                                 real(row_t, dp), int(row_q), int(obs_kind), int(obs_beam), &
                                 real(obs_s, dp), real(tol, dp), model, stat, &
                                 make_hist(hist_spec, hist_tab))
    end subroutine make_model

    !> Independent a priori information from the binding's columns [index, mean, sigma].
    pure type(prior_t) function make_prior(prior) result(pr)
        real(c_double), intent(in) :: prior(:, :)
        pr = prior_t(nint(prior(1, :)), real(prior(2, :), dp), real(prior(3, :), dp))
    end function make_prior

    !> The problem's observation list from the binding's arrays (kind code,
    !! beam and arc length s of each entry; beamid_observations).
    pure function make_obs(kind, beam, s) result(obs)
        integer(c_int), intent(in) :: kind(:), beam(:)
        real(c_double), intent(in) :: s(:)
        type(observation_t) :: obs(size(kind))
        obs = observation_list(int(kind), int(beam), real(s, dp))
    end function make_obs

    !> The release experiments' load histories from the binding's columns
    !! [experiment, beamid_loads' 9 values] and table rows (t, value).
    pure type(exp_histories_t) function make_hist(spec, tab) result(h)
        real(c_double), intent(in) :: spec(:, :), tab(:, :)
        h%spec = real(spec, dp)
        h%tab = real(tab, dp)
    end function make_hist

    !> The problem of beamid_ladder from a binding's arrays: the named
    !! specs (make_specs), the observation list, the load histories and the a
    !! priori information; max_iter > 0 replaces the fits' iteration limit.
    subroutine make_problem(nbeams, exp_kind, kv_exp, kv_key, kv_value, row_exp, row_t, row_q, &
                            obs_kind, obs_beam, obs_s, row_value, row_sigma, tol, hist_spec, &
                            hist_tab, prior, max_iter, pb, stat)
        integer(c_int), intent(in) :: nbeams, max_iter
        integer(c_int), intent(in) :: exp_kind(:), kv_exp(:), kv_key(:), row_exp(:), row_q(:)
        integer(c_int), intent(in) :: obs_kind(:), obs_beam(:)
        real(c_double), intent(in) :: kv_value(:), row_t(:), obs_s(:), row_value(:)
        real(c_double), intent(in) :: row_sigma(:), tol, hist_spec(:, :), hist_tab(:, :)
        real(c_double), intent(in) :: prior(:, :)
        type(problem_t), intent(out) :: pb
        type(status_t), intent(inout) :: stat
        type(experiment_spec_t), allocatable :: specs(:)
        call make_specs(exp_kind, kv_exp, kv_key, kv_value, specs, stat)
        if (stat%code /= STATUS_OK) return
        pb = problem_t(nbeams=int(nbeams), exp_kind=int(exp_kind), row_exp=int(row_exp), &
                       row_q=int(row_q), specs=specs, row_t=real(row_t, dp), &
                       y=real(row_value, dp), sigma=real(row_sigma, dp), tol=real(tol, dp), &
                       prior=make_prior(prior))
        if (max_iter > 0) pb%max_iter = int(max_iter)
        pb%hist = make_hist(hist_spec, hist_tab)
        pb%obs = make_obs(obs_kind, obs_beam, obs_s)
    end subroutine make_problem

    !> The candidate blocks cand_params(cand_start(c):cand_start(c+1)-1),
    !! named by their number c (the front names them).
    function make_cands(cand_start, cand_params, with_mesh) result(cs)
        integer(c_int), intent(in) :: cand_start(:), cand_params(:), with_mesh
        type(cand_set_t) :: cs
        integer :: c
        allocate (cs%cands(size(cand_start) - 1), cs%names(size(cand_start) - 1))
        do c = 1, size(cs%cands)
            cs%names(c) = fmt_int(c)
            cs%cands(c)%name = trim(cs%names(c))
            cs%cands(c)%params = int(cand_params(cand_start(c):cand_start(c + 1) - 1))
        end do
        ! bit 0: the mesh test; the improve ladder's row candidates: bit 1
        ! gross errors, bit 2 noise larger than stated (beamid_ladder row_rung)
        cs%with_mesh = btest(with_mesh, 0)
        cs%gross = btest(with_mesh, 1)
        cs%noise = btest(with_mesh, 2)
    end function make_cands

    !> Structure in time of one series of normalized residuals
    !! (beamid_dyn_diagnosis time_structure; out layout there).
    subroutine api_time_structure(n, t, r, out)
        integer(c_int), intent(in) :: n
        !f2py intent(hide) n
        real(c_double), intent(in) :: t(n), r(n)
        real(c_double), intent(out) :: out(10)
        call time_structure(real(t, dp), real(r, dp), out)
    end subroutine api_time_structure

    !> Diagnose a fit (beamid_ladder problem_diagnose: with release
    !! experiments beamid_dyn_diagnosis, of static experiments alone the
    !! static diagnosis). The base fit is evaluated at `params0` (the
    !! estimates; not refitted), every candidate block
    !! cand_params(cand_start(c):cand_start(c+1)-1) is score-tested and the
    !! leading ones refitted (from the first-order estimate, from the user's
    !! starting values `nominal` and by continuation). Outputs: copy_diag.
    subroutine api_problem_diagnose(nbeams, nparams, params0, nominal, nfree, free_idx, &
                                    nprior, prior, nexp, exp_kind, nkv, kv_exp, kv_key, kv_value, nrow, row_exp, &
                                    row_t, row_q, nobs, obs_kind, obs_beam, obs_s, row_value, &
                                    row_sigma, tol, nhs, hist_spec, nhtab, hist_tab, max_iter, &
                                    ncand, &
                                    cand_start, ncandp, cand_params, alpha, nrefit, &
                                    ambiguity_delta, collinear, with_mesh, cstats, pstats, &
                                    refit_params, ranking, cosine, dstats, refit_start, sep_t, &
                                    mstats, mesh_params, kept, notes, code, message)
        integer(c_int), intent(in) :: nhs, nhtab
        !f2py intent(hide) nhs, nhtab
        real(c_double), intent(in) :: hist_spec(10, nhs), hist_tab(2, nhtab)
        integer(c_int), intent(in) :: nbeams, nparams, nfree, nprior, nexp, nrow, max_iter
        !f2py intent(hide) nparams, nfree, nprior, nexp, nrow, ncand, ncandp
        real(c_double), intent(in) :: params0(nparams), nominal(nparams), prior(3, nprior)
        integer(c_int), intent(in) :: free_idx(nfree)
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        integer(c_int), intent(in) :: nobs
        !f2py intent(hide) nobs
        integer(c_int), intent(in) :: obs_kind(nobs), obs_beam(nobs)
        real(c_double), intent(in) :: obs_s(nobs)
        real(c_double), intent(in) :: row_t(nrow), row_value(nrow)
        real(c_double), intent(in) :: row_sigma(nrow), tol
        integer(c_int), intent(in) :: ncand, ncandp, nrefit, with_mesh
        integer(c_int), intent(in) :: cand_start(ncand + 1), cand_params(ncandp)
        real(c_double), intent(in) :: alpha, ambiguity_delta, collinear
        real(c_double), intent(out) :: cstats(18, ncand), pstats(6, ncandp)
        real(c_double), intent(out) :: refit_params(nparams, ncand), cosine(ncand, ncand)
        integer(c_int), intent(out) :: ranking(ncand), refit_start(ncand)
        real(c_double), intent(out) :: dstats(6), sep_t(ncand), mstats(10)
        real(c_double), intent(out) :: mesh_params(nparams)
        integer(c_int), intent(out) :: kept(ncandp)
        character(len=8192), intent(out) :: notes
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        integer(c_int), intent(in) :: nkv
        !f2py intent(hide) nkv
        integer(c_int), intent(in) :: kv_exp(nkv), kv_key(nkv)
        real(c_double), intent(in) :: kv_value(nkv)
        type(status_t) :: stat
        type(problem_t) :: pb
        type(fit_options_t) :: opts
        type(diagnose_options_t) :: dopts
        type(diag_out_t) :: dg
        type(cand_set_t) :: cs

        call make_problem(nbeams, exp_kind, kv_exp, kv_key, kv_value, row_exp, row_t, row_q, &
                          obs_kind, obs_beam, obs_s, row_value, row_sigma, tol, hist_spec, &
                          hist_tab, prior, 0, pb, stat)
        if (stat%code /= STATUS_OK) then
            call status_out(stat, code, message)
            return
        end if
        cs = make_cands(cand_start, cand_params, with_mesh)
        if (max_iter > 0) opts%max_iter = int(max_iter)
        dopts%alpha = alpha
        dopts%nrefit = int(nrefit)
        dopts%ambiguity_delta = ambiguity_delta
        dopts%collinear = collinear
        call problem_diagnose(pb, real(params0, dp), int(free_idx), real(nominal, dp), cs, &
                              opts, dopts, dg, stat)
        call status_out(stat, code, message)
        call copy_diag(dg, cs, stat%code == STATUS_OK, real(params0, dp), cstats, pstats, &
                       refit_params, ranking, cosine, dstats, refit_start, sep_t, mstats, &
                       mesh_params, kept, notes)
    end subroutine api_problem_diagnose

    !> Open an improve ladder (beamid_ladder ladder_start; the ladder
    !! beamid-batch runs): fit params0(free_idx) and hold the ladder under
    !! `handle` (> 0) until api_ladder_close(handle); then
    !! api_ladder_handle_step diagnoses (candidate blocks as
    !! api_problem_diagnose, with_mesh: test the mesh apart) and adds the
    !! verdict's effect, a rung per call, until none is significant at alpha
    !! or max_steps rungs were added. A failed start holds nothing (handle 0).
    subroutine api_ladder_open(nbeams, nparams, params0, nfree, free_idx, nprior, prior, nexp, &
                               exp_kind, nkv, kv_exp, kv_key, kv_value, nrow, row_exp, row_t, &
                               row_q, nobs, obs_kind, obs_beam, obs_s, row_value, row_sigma, &
                               tol, nhs, hist_spec, nhtab, hist_tab, max_iter, ncand, &
                               cand_start, ncandp, cand_params, with_mesh, alpha, max_steps, &
                               handle, code, message)
        integer(c_int), intent(in) :: nhs, nhtab
        !f2py intent(hide) nhs, nhtab
        real(c_double), intent(in) :: hist_spec(10, nhs), hist_tab(2, nhtab)
        integer(c_int), intent(in) :: nbeams, nparams, nfree, nprior, nexp, nrow, max_iter
        !f2py intent(hide) nparams, nfree, nprior, nexp, nrow, ncand, ncandp
        real(c_double), intent(in) :: params0(nparams), prior(3, nprior)
        integer(c_int), intent(in) :: free_idx(nfree)
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        integer(c_int), intent(in) :: nobs
        !f2py intent(hide) nobs
        integer(c_int), intent(in) :: obs_kind(nobs), obs_beam(nobs)
        real(c_double), intent(in) :: obs_s(nobs)
        real(c_double), intent(in) :: row_t(nrow), row_value(nrow)
        real(c_double), intent(in) :: row_sigma(nrow), tol
        integer(c_int), intent(in) :: ncand, ncandp, with_mesh, max_steps
        integer(c_int), intent(in) :: cand_start(ncand + 1), cand_params(ncandp)
        real(c_double), intent(in) :: alpha
        integer(c_int), intent(out) :: handle
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        integer(c_int), intent(in) :: nkv
        !f2py intent(hide) nkv
        integer(c_int), intent(in) :: kv_exp(nkv), kv_key(nkv)
        real(c_double), intent(in) :: kv_value(nkv)
        type(status_t) :: stat
        type(problem_t) :: pb
        integer :: h
        handle = 0
        call make_problem(nbeams, exp_kind, kv_exp, kv_key, kv_value, row_exp, row_t, row_q, &
                          obs_kind, obs_beam, obs_s, row_value, row_sigma, tol, hist_spec, &
                          hist_tab, prior, max_iter, pb, stat)
        if (stat%code /= STATUS_OK) then
            call status_out(stat, code, message)
            return
        end if
        call run_open(RUN_LADDER, h)
        call ladder_start(runs(h)%lad, pb, real(params0, dp), int(free_idx), &
                          make_cands(cand_start, cand_params, with_mesh), real(alpha, dp), &
                          int(max_steps), stat)
        call status_out(stat, code, message)
        if (stat%code == STATUS_OK) then
            handle = int(h, c_int)
        else
            call run_close(h, RUN_LADDER)
        end if
    end subroutine api_ladder_open

    !> Release the ladder of `handle` (a closed or unknown handle: nothing
    !! happens).
    subroutine api_ladder_close(handle)
        integer(c_int), intent(in) :: handle
        call run_close(int(handle), RUN_LADDER)
    end subroutine api_ladder_close

    !> The number of ladders held (handles not yet closed).
    subroutine api_ladder_handles_open(n)
        integer(c_int), intent(out) :: n
        n = int(runs_held(RUN_LADDER), c_int)
    end subroutine api_ladder_handles_open

    !> Is handle an open ladder? (else code ERR_INPUT naming it)
    logical function ladder_ok(handle, code, message)
        integer(c_int), intent(in) :: handle
        integer(c_int), intent(out) :: code
        character(len=*), intent(out) :: message
        ladder_ok = run_ok(handle, RUN_LADDER, code, message)
    end function ladder_ok

    !> The ladder of handle, as refusals name it.
    function whose(handle) result(text)
        integer(c_int), intent(in) :: handle
        character(len=:), allocatable :: text
        text = 'the ladder of handle '//fmt_int(int(handle))
    end function whose

    !> One rung of the ladder of `handle` (beamid_ladder ladder_step):
    !! nrung rungs are done; done = 1 when the ladder has ended (an ended
    !! ladder is not stepped: nrung is its count).
    subroutine api_ladder_handle_step(handle, nrung, done, code, message)
        integer(c_int), intent(in) :: handle
        integer(c_int), intent(out) :: nrung, done, code
        character(len=65536), intent(out) :: message
        type(status_t) :: stat
        if (.not. ladder_ok(handle, code, message)) return
        associate (lad => runs(handle)%lad)
            call ladder_step(lad, stat)
            nrung = int(lad%n, c_int)
            done = merge(1_c_int, 0_c_int, lad%done)
        end associate
        call status_out(stat, code, message)
    end subroutine api_ladder_handle_step

    !> Rung k of the ladder of `handle`: effect ('start', the number of the
    !! candidate added, or 'mesh (N elements per beam)'), info = [free
    !! parameters, elements per beam of the releases (0: as given), the
    !! start the verdict's refit kept (START_*), data rows, the fits' iteration
    !! limit], the free parameters free_idx (an
    !! argument named `free` would shadow C's free() in f2py's wrapper), those
    !! the rung switched on and those it set back (index lists, zeros after),
    !! where its fit started and the nominal model of its refits.
    subroutine api_ladder_handle_rung(handle, k, nparams, info, free_idx, added, removed, start, &
                                      nominal, effect, code, message)
        integer(c_int), intent(in) :: handle, k, nparams
        integer(c_int), intent(out) :: info(5), free_idx(nparams), added(nparams)
        integer(c_int), intent(out) :: removed(nparams)
        real(c_double), intent(out) :: start(nparams), nominal(nparams)
        character(len=64), intent(out) :: effect
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        effect = ''
        if (.not. ladder_ok(handle, code, message)) return
        call rung_out(runs(handle)%lad, k, nparams, whose(handle), info, free_idx, added, &
                      removed, start, nominal, effect, code, message)
    end subroutine api_ladder_handle_rung

    !> The fit of rung k of the ladder of `handle` (outputs as api_fit_effect).
    subroutine api_ladder_handle_fit(handle, k, nparams, nfree, nrow, max_iter, params, sigmas, &
                                     cov, corr, flags, predictions, normalized, stats, &
                                     log_cost, log_lambda, log_step, log_params, info, code, &
                                     message, note)
        integer(c_int), intent(in) :: handle, k, nparams, nfree, nrow, max_iter
        real(c_double), intent(out) :: params(nparams), sigmas(nfree), cov(nfree, nfree)
        real(c_double), intent(out) :: corr(nfree, nfree), predictions(nrow), normalized(nrow)
        integer(c_int), intent(out) :: flags(nfree), info(2)
        real(c_double), intent(out) :: stats(8)
        real(c_double), intent(out) :: log_cost(max_iter + 1), log_lambda(max_iter + 1)
        real(c_double), intent(out) :: log_step(max_iter + 1), log_params(nfree, max_iter + 1)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        character(len=8192), intent(out) :: note
        note = ''
        if (.not. ladder_ok(handle, code, message)) return
        call rung_fit_out(runs(handle)%lad, k, nparams, nfree, nrow, whose(handle), params, &
                          sigmas, cov, corr, flags, predictions, normalized, stats, log_cost, &
                          log_lambda, log_step, log_params, info, code, message, note)
    end subroutine api_ladder_handle_fit

    !> The rows of rung k's fit of the ladder of `handle` as the measurement
    !! chain's treatments judged them (beamid_chain_fit): per row its last
    !! weight, the sigma it was judged with, that sigma's standard deviation
    !! and 1 for a gross error; has = 0 for a plain fit (nothing set).
    subroutine api_ladder_handle_rows(handle, k, nrow, weights, sigma_used, sigma_sd, flagged, &
                                      has, code, message)
        integer(c_int), intent(in) :: handle, k, nrow
        real(c_double), intent(out) :: weights(nrow), sigma_used(nrow), sigma_sd(nrow)
        integer(c_int), intent(out) :: flagged(nrow), has, code
        character(len=256), intent(out) :: message
        if (.not. ladder_ok(handle, code, message)) return
        call rung_rows_out(runs(handle)%lad, k, nrow, whose(handle), weights, sigma_used, &
                           sigma_sd, flagged, has, code, message)
    end subroutine api_ladder_handle_rows

    !> The diagnosis of rung k of the ladder of `handle` (outputs as
    !! api_problem_diagnose).
    subroutine api_ladder_handle_diag(handle, k, nparams, ncand, ncandp, cstats, pstats, &
                                      refit_params, ranking, cosine, dstats, refit_start, sep_t, &
                                      mstats, mesh_params, kept, notes, code, message)
        integer(c_int), intent(in) :: handle, k, nparams, ncand, ncandp
        real(c_double), intent(out) :: cstats(18, ncand), pstats(6, ncandp)
        real(c_double), intent(out) :: refit_params(nparams, ncand), cosine(ncand, ncand)
        integer(c_int), intent(out) :: ranking(ncand), refit_start(ncand)
        real(c_double), intent(out) :: dstats(6), sep_t(ncand), mstats(10)
        real(c_double), intent(out) :: mesh_params(nparams)
        integer(c_int), intent(out) :: kept(ncandp)
        character(len=8192), intent(out) :: notes
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        notes = ''
        if (.not. ladder_ok(handle, code, message)) return
        call rung_diag_out(runs(handle)%lad, k, nparams, ncand, ncandp, whose(handle), &
                           cstats, pstats, refit_params, ranking, cosine, dstats, refit_start, &
                           sep_t, mstats, mesh_params, kept, notes, code, message)
    end subroutine api_ladder_handle_diag

    !> The mesh check of a finished fit (beamid_dyn_diagnosis mesh_check):
    !! the data rows' predictions at `params` with every release at twice its
    !! elements per beam against the fit's `pred`. out = [done (1/0), elements
    !! per beam now, recommended, largest |change| / sigma, its data row
    !! (1-based), chi-square of the refined model at params].
    subroutine api_mesh_check(nbeams, nparams, params, nexp, exp_kind, nkv, kv_exp, kv_key, kv_value, nrow, &
                              row_exp, row_t, row_q, nobs, obs_kind, obs_beam, obs_s, row_value, &
                              row_sigma, pred, tol, nhs, hist_spec, nhtab, hist_tab, out, code, message)
        integer(c_int), intent(in) :: nhs, nhtab
        !f2py intent(hide) nhs, nhtab
        real(c_double), intent(in) :: hist_spec(10, nhs), hist_tab(2, nhtab)
        integer(c_int), intent(in) :: nbeams, nparams, nexp, nrow
        !f2py intent(hide) nparams, nexp, nrow
        real(c_double), intent(in) :: params(nparams), row_t(nrow)
        integer(c_int), intent(in) :: exp_kind(nexp), row_exp(nrow), row_q(nrow)
        integer(c_int), intent(in) :: nobs
        !f2py intent(hide) nobs
        integer(c_int), intent(in) :: obs_kind(nobs), obs_beam(nobs)
        real(c_double), intent(in) :: obs_s(nobs)
        real(c_double), intent(in) :: row_value(nrow), row_sigma(nrow), pred(nrow), tol
        real(c_double), intent(out) :: out(6)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        integer(c_int), intent(in) :: nkv
        !f2py intent(hide) nkv
        integer(c_int), intent(in) :: kv_exp(nkv), kv_key(nkv)
        real(c_double), intent(in) :: kv_value(nkv)
        type(experiment_spec_t), allocatable :: specs(:)
        type(mesh_test_t) :: res
        type(status_t) :: stat
        call make_specs(exp_kind, kv_exp, kv_key, kv_value, specs, stat)
        if (stat%code /= STATUS_OK) then
            call status_out(stat, code, message)
            return
        end if
        call mesh_check(int(nbeams), int(exp_kind), specs, int(row_exp), &
                        real(row_t, dp), int(row_q), real(tol, dp), real(params, dp), &
                        real(row_value, dp), real(row_sigma, dp), real(pred, dp), res, stat, &
                        make_obs(obs_kind, obs_beam, obs_s), &
                        hist=make_hist(hist_spec, hist_tab))
        call status_out(stat, code, message)
        out = [merge(1.0_dp, 0.0_dp, res%done), real(res%nepb, dp), real(res%recommended, dp), &
               res%max_change, real(res%max_row, dp), res%chi2]
    end subroutine api_mesh_check

    !> Monte Carlo replicates of one fit (beamid.consistency; library
    !! beamid_replicates fit_replicates): the problem of api_fit_effect's
    !! arrays (no effect block, independent a priori information) fitted from
    !! params0 on each column r of ys (the rows' values) with a priori means
    !! means(:, r) (prior's indices and sigmas). Per replicate: the full
    !! parameter vector, the sigmas and flags of the free parameters, the
    !! fit's stats (api_code_names table 5), how it ended (STOP_*) and its
    !! status code (codes; 0: the fit ended, converged or flagged). code and
    !! message: the arrays' shapes.
    subroutine api_fit_replicates(nbeams, nparams, params0, nfree, free_idx, nprior, prior, &
                                  nexp, exp_kind, nkv, kv_exp, kv_key, kv_value, nrow, row_exp, &
                                  row_t, row_q, nobs, obs_kind, obs_beam, obs_s, row_sigma, tol, &
                                  nhs, hist_spec, nhtab, hist_tab, max_iter, nrep, ys, nmean, &
                                  means, params, sigmas, flags, stats, stops, codes, code, message)
        integer(c_int), intent(in) :: nbeams, nparams, nfree, nprior, nexp, nkv, nrow, nobs
        !f2py intent(hide) nparams, nfree, nprior, nexp, nkv, nrow, nobs
        integer(c_int), intent(in) :: nhs, nhtab, nrep, max_iter, nmean
        !f2py intent(hide) nhs, nhtab, nrep, nmean
        real(c_double), intent(in) :: params0(nparams), prior(3, nprior)
        integer(c_int), intent(in) :: free_idx(nfree), exp_kind(nexp)
        integer(c_int), intent(in) :: kv_exp(nkv), kv_key(nkv)
        real(c_double), intent(in) :: kv_value(nkv)
        integer(c_int), intent(in) :: row_exp(nrow), row_q(nrow)
        real(c_double), intent(in) :: row_t(nrow), row_sigma(nrow), tol
        integer(c_int), intent(in) :: obs_kind(nobs), obs_beam(nobs)
        real(c_double), intent(in) :: obs_s(nobs)
        real(c_double), intent(in) :: hist_spec(10, nhs), hist_tab(2, nhtab)
        !> the a priori means column by column (nprior x nrep; flat, so that
        !! no prior passes as an empty array)
        real(c_double), intent(in) :: ys(nrow, nrep), means(nmean)
        real(c_double), intent(out) :: params(nparams, nrep), sigmas(nfree, nrep)
        integer(c_int), intent(out) :: flags(nfree, nrep), stops(nrep), codes(nrep)
        real(c_double), intent(out) :: stats(8, nrep)
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(status_t) :: stat
        type(fit_options_t) :: opts
        type(replicate_out_t) :: out
        type(experiment_spec_t), allocatable :: specs(:)

        params = spread(params0, 2, nrep)
        sigmas = 0.0_c_double
        flags = 0
        stats = 0.0_c_double
        stops = 0
        codes = 0
        call make_options(max_iter, 0.0_c_double, 0.0_c_double, opts)
        if (nmean /= nprior*nrep) then
            call set_status(stat, ERR_INPUT, 'replicates', 'a priori means '// &
                            fmt_int(int(nmean))//', expected nprior x nrep = '// &
                            fmt_int(int(nprior*nrep)))
        else
            call make_specs(exp_kind, kv_exp, kv_key, kv_value, specs, stat)
        end if
        if (stat%code == STATUS_OK) &
            call fit_replicates(int(nbeams), int(exp_kind), specs, int(row_exp), &
                                real(row_t, dp), int(row_q), int(obs_kind), int(obs_beam), &
                                real(obs_s, dp), real(tol, dp), real(row_sigma, dp), &
                                real(prior, dp), make_hist(hist_spec, hist_tab), &
                                real(params0, dp), int(free_idx), opts, real(ys, dp), &
                                reshape(real(means, dp), [int(nprior), int(nrep)]), out, stat)
        call status_out(stat, code, message)
        if (stat%code /= STATUS_OK) return
        params = out%params
        sigmas = out%sigmas
        flags = int(out%flags, c_int)
        stats = out%stats(1:NREP_STATS, :)
        stops = int(out%stop, c_int)
        codes = int(out%code, c_int)
    end subroutine api_fit_replicates

    !> The registry of experiment families (beamid_families), a line each:
    !! name, tab, 1 when its rows are records in time (timed), tab, the spec
    !! key holding its elements per beam ('' when it has no mesh), tab, its
    !! experiment kinds as code:words separated by commas. The fronts ask it
    !! what a family is instead of asking which class an experiment is.
    subroutine api_family_table(text, code, message)
        character(len=4096), intent(out) :: text
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        character(len=:), allocatable :: t, kinds, mesh
        type(family_slot_t), allocatable :: reg(:)
        integer, allocatable :: codes(:)
        integer :: f, k, key
        call registered_families(reg)
        t = ''
        do f = 1, size(reg)
            kinds = ''
            codes = reg(f)%item%kind_codes()
            do k = 1, size(codes)
                if (len(kinds) > 0) kinds = kinds//','
                kinds = kinds//fmt_int(codes(k))//':'//reg(f)%item%kind_label(codes(k))
            end do
            mesh = ''
            key = reg(f)%item%mesh_key()
            if (key > 0 .and. key <= size(SPEC_KEYS)) mesh = trim(SPEC_KEYS(key)%name)
            if (f > 1) t = t//new_line('a')
            t = t//reg(f)%item%name()//achar(9)//merge('1', '0', reg(f)%item%timed())// &
                achar(9)//mesh//achar(9)//kinds
        end do
        call table_out(t, 'api_family_table', text, code, message)
    end subroutine api_family_table

end module beamid_api_estimation
