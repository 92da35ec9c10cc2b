!> f2py-facing API of the deck and measurement readers and of the task
!! runners: Python reads decks and measurement CSVs and runs decks through
!! the same Fortran as beamid-batch (docs/decks.md).
!!
!! A deck is read once per run: api_deck_open reads and validates it and the
!! measurement files it names (beamid_deck_run) into a slot of the binding's
!! handle table (beamid_api_runs)
!! and returns its handle; the caller owns the handle (the Python object
!! beamid._core.DeckHandle) and releases it with api_deck_close. Every other
!! deck entry takes the handle: the sizes and scalars (api_deck_handle_sizes),
!! the arrays (api_deck_handle_arrays), the measurement rows
!! (api_deck_handle_data), the task run at once (api_deck_handle_task), or an
!! estimation task in steps (api_deck_handle_start, _step, then the rungs'
!! results returned by api_deck_handle_rung, _fit, _diag, and the files
!! written by api_deck_handle_write). No slot is found by path; what a run
!! computed is held by its handle only. Messages: every problem, one per line.
!! Outputs of a failed call are zeros: f2py allocates output arrays zeroed and
!! declares output scalars = 0 (characters blank), so no entry zeroes them.
module beamid_api_deck
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, status_out, put_text, fmt_int, STATUS_OK, ERR_INPUT, &
                             exit_code, set_status
    use beamid_deck, only: deck_t
    use beamid_tasks, only: deck_specs
    use beamid_deck_run, only: deck_run_t, deck_run_open, deck_run_task, deck_run_start, &
                               deck_run_step, deck_run_write
    use beamid_api_marshal, only: rung_out, rung_fit_out, rung_diag_out, rung_rows_out
    use beamid_api_runs, only: runs, RUN_DECK, run_open, run_close, runs_held, run_ok
    use beamid_measurements, only: measurements_t, read_measurements
    use beamid_observations, only: kind_label, NKIND, kind_table_text, observation_t, &
                                   parse_observation, obs_label, obs_groups
    implicit none
    private

    public :: api_deck_open, api_deck_close, api_deck_handle_sizes, api_deck_handle_arrays, &
              api_deck_handle_spec_size, api_deck_handle_specs, &
              api_deck_handle_data_size, api_deck_handle_data, api_deck_handle_task, &
              api_deck_handle_start, api_deck_handle_step, api_deck_handle_rung, &
              api_deck_handle_fit, api_deck_handle_diag, api_deck_handle_rows, &
              api_deck_handle_write, &
              api_deck_handles_open
    public :: api_measurements_size, &
              api_measurements_read, api_exit_code, api_quantity_labels, &
              api_observation_table, api_observation_parse, api_deck_handle_history_sizes, &
              api_deck_handle_histories

    !> Length of the messages and texts exchanged here.
    integer, parameter :: TEXT_LEN = 65536

contains

    !> Exit code of a status code (beamid_status exit_code).
    subroutine api_exit_code(code, ecode)
        integer(c_int), intent(in) :: code
        integer(c_int), intent(out) :: ecode
        ecode = int(exit_code(int(code)), c_int)
    end subroutine api_exit_code

    !> All problems of a read, one per line, into message.
    subroutine put_errors(deck, stat, code, message)
        type(deck_t), intent(in) :: deck
        type(status_t), intent(in) :: stat
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        call status_out(stat, code, message)
        if (allocated(deck%errors)) then
            if (len(deck%errors) > 0) call put_text(deck%errors, message)
        end if
    end subroutine put_errors

    !> The sizes and scalars of the deck of `handle` (api_deck_open). sizes:
    !! nbeams, nparams, nwrt, nt (output times), nexp, nfree, nprior, ncand,
    !! ndata (measurement rows), has_load,
    !! shape_points, fe_elements_per_beam, fe_moment_form, fe_rotary_inertia,
    !! fe_point_masses, fe_steps, sim_elements_per_beam, sim_integrator,
    !! sim_friction, max_iter, load_kind. reals: load fx, fy, moment,
    !! wire_length, tol, fe_tol, sim_dt, sim_rtol, sim_atol, sim_motor_gain,
    !! sim_friction_velocity, alpha. text: task, output, data path, then the
    !! experiment names and the candidates, one per line, then the &published
    !! lines (deck_t%published), then for task identify one line per stage
    !! (deck_t%stage_text), then the &sensor table and the &fit groups that
    !! read a logger file (deck_t%channel_text).
    subroutine api_deck_handle_sizes(handle, sizes, reals, text, code, message)
        integer(c_int), intent(in) :: handle
        integer(c_int), intent(out) :: sizes(21)
        real(c_double), intent(out) :: reals(12)
        character(len=65536), intent(out) :: text
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        character(len=:), allocatable :: t
        integer :: i
        text = ''
        if (.not. handle_ok(handle, code, message)) return
        associate (d => runs(handle)%deck%deck)
        sizes = int([d%nbeams, size(d%params), nsize_i(d%wrt), nsize_r(d%sim_t_out), &
                     nexp(d), nsize_i(d%free), nsize_i(d%prior_index), ncand(d), &
                     nsize_r(d%data%value), merge(1, 0, d%has_load), d%shape_points, &
                     d%fe_elements_per_beam, d%fe_moment_form, merge(1, 0, d%fe_rotary_inertia), &
                     merge(1, 0, d%fe_point_masses), d%fe_steps, d%sim_elements_per_beam, &
                     d%sim_integrator, d%sim_friction, d%max_iter, d%load%kind], c_int)
        reals = [d%load%fx, d%load%fy, d%load%moment, d%load%wire_length, d%tol, d%fe_tol, &
                 d%sim_dt, d%sim_rtol, d%sim_atol, d%sim_motor_gain, d%sim_friction_velocity, &
                 d%alpha]
        t = runs(handle)%deck%task//new_line('a')//runs(handle)%deck%output//new_line('a')
        if (allocated(d%data_path)) t = t//d%data_path
        t = t//new_line('a')
        do i = 1, nexp(d)
            t = t//trim(d%exp_names(i))//new_line('a')
        end do
        do i = 1, ncand(d)
            t = t//trim(d%candidates(i))//new_line('a')
        end do
        t = t//d%published
        if (allocated(d%stage_text)) t = t//d%stage_text   ! task identify: 'S' lines
        if (allocated(d%channel_text)) t = t//d%channel_text   ! &sensor 'N', logger 'C' lines
        if (len(t) > TEXT_LEN) then
            code = int(ERR_INPUT, c_int)
            message = d%path//': the names of the deck are too long (over '// &
                      fmt_int(TEXT_LEN)//' characters)'
            return
        end if
        text = t
        end associate
    end subroutine api_deck_handle_sizes

    !> size(a), 0 when a is not allocated.
    pure integer function nsize_i(a)
        integer, allocatable, intent(in) :: a(:)
        nsize_i = 0
        if (allocated(a)) nsize_i = size(a)
    end function nsize_i

    !> size(a), 0 when a is not allocated.
    pure integer function nsize_r(a)
        real(dp), allocatable, intent(in) :: a(:)
        nsize_r = 0
        if (allocated(a)) nsize_r = size(a)
    end function nsize_r

    !> The sizes of the &history groups of the deck of `handle`
    !! (beamid_deck_history): nh histories, ntab table rows
    !! (api_deck_handle_histories returns them).
    subroutine api_deck_handle_history_sizes(handle, nh, ntab, code, message)
        integer(c_int), intent(in) :: handle
        integer(c_int), intent(out) :: nh, ntab
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        nh = 0
        ntab = 0
        if (.not. handle_ok(handle, code, message)) return
        associate (d => runs(handle)%deck%deck)
            if (allocated(d%hist%spec)) nh = int(size(d%hist%spec, 2), c_int)
            if (allocated(d%hist%tab)) ntab = int(size(d%hist%tab, 2), c_int)
        end associate
    end subroutine api_deck_handle_history_sizes

    !> The &history groups of the deck of `handle`: a column [experiment
    !! (1-based; a simulate deck's: 1), beamid_loads' 9 values] per history
    !! and the table rows (t, value) they refer to (sizes from
    !! api_deck_handle_history_sizes).
    subroutine api_deck_handle_histories(handle, nh, ntab, spec, tab, code, message)
        integer(c_int), intent(in) :: handle, nh, ntab
        real(c_double), intent(out) :: spec(10, nh), tab(2, ntab)
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        spec = 0.0_c_double
        tab = 0.0_c_double
        if (.not. handle_ok(handle, code, message)) return
        associate (d => runs(handle)%deck%deck)
            if (.not. allocated(d%hist%spec)) return
            if (size(d%hist%spec, 2) /= nh .or. size(d%hist%tab, 2) /= ntab) then
                code = int(ERR_INPUT, c_int)
                message = d%path//': nh = '//fmt_int(int(nh))//', ntab = '// &
                          fmt_int(int(ntab))//', expected '//fmt_int(size(d%hist%spec, 2))// &
                          ' and '//fmt_int(size(d%hist%tab, 2))// &
                          ' (api_deck_handle_history_sizes)'
                return
            end if
            spec = real(d%hist%spec, c_double)
            tab = real(d%hist%tab, c_double)
        end associate
    end subroutine api_deck_handle_histories

    pure integer function nexp(d)
        type(deck_t), intent(in) :: d
        nexp = 0
        if (allocated(d%experiments)) nexp = size(d%experiments)
    end function nexp

    pure integer function ncand(d)
        type(deck_t), intent(in) :: d
        ncand = 0
        if (allocated(d%candidates)) ncand = size(d%candidates)
    end function ncand

    !> The arrays of a deck (sizes from api_deck_handle_sizes): parameters,
    !! wrt and free parameter indices (1-based), output times, priors. Its
    !! experiments: api_deck_handle_specs.
    subroutine api_deck_handle_arrays(handle, nparams, nwrt, nt, nfree, nprior, params, wrt, &
                                      t_out, free_idx, prior_index, prior_mean, prior_sigma, &
                                      code, message)
        integer(c_int), intent(in) :: handle
        integer(c_int), intent(in) :: nparams, nwrt, nt, nfree, nprior
        real(c_double), intent(out) :: params(nparams), t_out(nt)
        real(c_double), intent(out) :: prior_mean(nprior), prior_sigma(nprior)
        integer(c_int), intent(out) :: wrt(nwrt), free_idx(nfree)
        integer(c_int), intent(out) :: prior_index(nprior)
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        if (.not. handle_ok(handle, code, message)) return
        associate (d => runs(handle)%deck%deck)
        if (size(d%params) /= nparams .or. nsize_i(d%wrt) /= nwrt .or. &
            nsize_i(d%free) /= nfree .or. nsize_i(d%prior_index) /= nprior .or. &
            nsize_r(d%sim_t_out) /= nt) then
            code = int(ERR_INPUT, c_int)
            message = d%path//': nparams = '//fmt_int(int(nparams))//', nwrt = '// &
                      fmt_int(int(nwrt))//', nt = '//fmt_int(int(nt))//', nfree = '// &
                      fmt_int(int(nfree))//', nprior = '//fmt_int(int(nprior))// &
                      ', expected the sizes of api_deck_handle_sizes'
            return
        end if
        params = d%params
        if (nwrt > 0) wrt = int(d%wrt(:nwrt), c_int)
        if (nt > 0) t_out = d%sim_t_out(:nt)
        if (nfree > 0) free_idx = int(d%free(:nfree), c_int)
        if (nprior > 0) then
            prior_index = int(d%prior_index(:nprior), c_int)
            prior_mean = d%prior_mean(:nprior)
            prior_sigma = d%prior_sigma(:nprior)
        end if
        end associate
    end subroutine api_deck_handle_arrays

    !> The number of named spec triples of the deck of `handle`
    !! (api_deck_handle_specs).
    subroutine api_deck_handle_spec_size(handle, nkv, code, message)
        integer(c_int), intent(in) :: handle
        integer(c_int), intent(out) :: nkv, code
        character(len=65536), intent(out) :: message
        integer, allocatable :: kinds(:), kv_exp(:), kv_key(:)
        real(dp), allocatable :: kv_value(:)
        nkv = 0
        if (.not. handle_ok(handle, code, message)) return
        call deck_specs(runs(handle)%deck%deck, kinds, kv_exp, kv_key, kv_value)
        nkv = int(size(kv_exp), c_int)
    end subroutine api_deck_handle_spec_size

    !> The experiments of the deck of `handle` (nexp from
    !! api_deck_handle_sizes, nkv from api_deck_handle_spec_size): each one's
    !! kind and its named spec as triples (experiment, key of the core's key
    !! table api_spec_keys, value; every key of each experiment, the form the
    !! estimation entries take: beamid_tasks deck_specs).
    subroutine api_deck_handle_specs(handle, nexp_, nkv, exp_kind, kv_exp, kv_key, kv_value, &
                                     code, message)
        integer(c_int), intent(in) :: handle, nexp_, nkv
        integer(c_int), intent(out) :: exp_kind(nexp_), kv_exp(nkv), kv_key(nkv)
        real(c_double), intent(out) :: kv_value(nkv)
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        integer, allocatable :: kinds(:), e(:), k(:)
        real(dp), allocatable :: v(:)
        if (.not. handle_ok(handle, code, message)) return
        call deck_specs(runs(handle)%deck%deck, kinds, e, k, v)
        if (size(kinds) /= nexp_ .or. size(e) /= nkv) then
            code = int(ERR_INPUT, c_int)
            message = runs(handle)%deck%deck%path//': nexp = '//fmt_int(int(nexp_))// &
                      ', nkv = '//fmt_int(int(nkv))//', expected '//fmt_int(size(kinds))// &
                      ' and '//fmt_int(size(e))//' (api_deck_handle_sizes, _spec_size)'
            return
        end if
        exp_kind = int(kinds, c_int)
        kv_exp = int(e, c_int)
        kv_key = int(k, c_int)
        kv_value = real(v, c_double)
    end subroutine api_deck_handle_specs

    !> Read and validate the deck at `path` and the measurement files it names
    !! (once: beamid_deck_run deck_run_open) and hold it under `handle` (> 0)
    !! until api_deck_close(handle). A deck with problems is not held
    !! (handle 0): every problem, one per line, in message. fit_keys: &fit
    !! items given apart (beamid_deck read_deck; blank: none).
    subroutine api_deck_open(path, fit_keys, handle, code, message)
        character(len=*), intent(in) :: path, fit_keys
        integer(c_int), intent(out) :: handle
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        type(status_t) :: stat
        integer :: h
        call run_open(RUN_DECK, h)
        call deck_run_open(trim(path), runs(h)%deck, stat, fit_keys)
        call put_errors(runs(h)%deck%deck, stat, code, message)
        handle = 0
        if (stat%code == STATUS_OK) then
            handle = int(h, c_int)
        else
            call run_close(h, RUN_DECK)
        end if
    end subroutine api_deck_open

    !> Release the deck of `handle` and what its run computed (a closed or
    !! unknown handle: nothing happens).
    subroutine api_deck_close(handle)
        integer(c_int), intent(in) :: handle
        call run_close(int(handle), RUN_DECK)
    end subroutine api_deck_close

    !> The number of decks held (handles not yet closed).
    subroutine api_deck_handles_open(n)
        integer(c_int), intent(out) :: n
        n = int(runs_held(RUN_DECK), c_int)
    end subroutine api_deck_handles_open

    !> Is handle an open deck? (else code ERR_INPUT naming it)
    logical function handle_ok(handle, code, message)
        integer(c_int), intent(in) :: handle
        integer(c_int), intent(out) :: code
        character(len=*), intent(out) :: message
        handle_ok = run_ok(handle, RUN_DECK, code, message)
    end function handle_ok

    !> Run the task of the deck of `handle` as beamid-batch does
    !! (beamid_deck_run deck_run_task): the files written, one per line, in
    !! `written`. A non-blank `task` replaces the deck's (`beamid
    !! fit|compare|diagnose|improve DECK`): an estimation task for an
    !! estimation deck only.
    subroutine api_deck_handle_task(handle, task, written, summary, code, message)
        integer(c_int), intent(in) :: handle
        character(len=*), intent(in) :: task
        character(len=65536), intent(out) :: written
        !> the summary line beamid-batch prints (run_task)
        character(len=4096), intent(out) :: summary
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        type(status_t) :: stat
        character(len=:), allocatable :: files, line
        written = ''
        summary = ''
        if (.not. handle_ok(handle, code, message)) return
        call deck_run_task(runs(handle)%deck, trim(task), files, line, stat)
        if (stat%code == STATUS_OK) call put_text(files, written)
        if (stat%code == STATUS_OK) summary = line
        call put_errors(runs(handle)%deck%deck, stat, code, message)
    end subroutine api_deck_handle_task

    !> Start the ladder of the estimation deck of `handle` run as `task`
    !! (blank: the deck's; beamid_deck_run deck_run_start: the fit,
    !! undiagnosed for fit and compare; of an identify deck the fit of
    !! `stage`, 1-based, from the stages fitted by the calls before); step
    !! it with api_deck_handle_step, read it with api_deck_handle_rung, _fit
    !! and _diag, write the deck's files with api_deck_handle_write.
    subroutine api_deck_handle_start(handle, task, stage, code, message)
        integer(c_int), intent(in) :: handle
        character(len=*), intent(in) :: task
        integer(c_int), intent(in) :: stage
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        type(status_t) :: stat
        if (.not. handle_ok(handle, code, message)) return
        call deck_run_start(runs(handle)%deck, trim(task), int(stage), stat)
        call status_out(stat, code, message)
    end subroutine api_deck_handle_start

    !> One rung of the ladder of `handle` (beamid_deck_run deck_run_step):
    !! nrung rungs are done; done = 1 when the ladder has ended (an ended
    !! ladder is not stepped: nrung is its count).
    subroutine api_deck_handle_step(handle, nrung, done, code, message)
        integer(c_int), intent(in) :: handle
        integer(c_int), intent(out) :: nrung, done, code
        character(len=65536), intent(out) :: message
        type(status_t) :: stat
        if (.not. handle_ok(handle, code, message)) return
        associate (run => runs(handle)%deck)
            if (run%started .and. .not. run%lad%done) call deck_run_step(run, stat)
            if (.not. run%started) call deck_run_step(run, stat)   ! its refusal
            nrung = int(run%lad%n, c_int)
            done = merge(1_c_int, 0_c_int, run%lad%done)
        end associate
        call status_out(stat, code, message)
    end subroutine api_deck_handle_step

    !> Rung k of the ladder of `handle` (outputs as beamid_api_estimation
    !! api_ladder_handle_rung): effect, info = [free parameters, elements per beam
    !! of the releases, the start the refit kept, data rows, the fits'
    !! iteration limit], free_idx, added, removed, start, nominal.
    subroutine api_deck_handle_rung(handle, k, nparams, info, free_idx, added, removed, start, &
                                    nominal, effect, code, message)
        integer(c_int), intent(in) :: handle, k, nparams
        integer(c_int), intent(out) :: info(5), free_idx(nparams), added(nparams)
        integer(c_int), intent(out) :: removed(nparams)
        real(c_double), intent(out) :: start(nparams), nominal(nparams)
        character(len=64), intent(out) :: effect
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        effect = ''
        if (.not. handle_ok(handle, code, message)) return
        call rung_out(runs(handle)%deck%lad, k, nparams, whose(handle), info, free_idx, added, &
                      removed, start, nominal, effect, code, message)
    end subroutine api_deck_handle_rung

    !> The fit of rung k of the ladder of `handle` (outputs as
    !! beamid_api_estimation api_fit_effect).
    subroutine api_deck_handle_fit(handle, k, nparams, nfree, nrow, max_iter, params, sigmas, &
                                   cov, corr, flags, predictions, normalized, stats, log_cost, &
                                   log_lambda, log_step, log_params, info, code, message, note)
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
        if (.not. handle_ok(handle, code, message)) return
        call rung_fit_out(runs(handle)%deck%lad, k, nparams, nfree, nrow, whose(handle), params, &
                          sigmas, cov, corr, flags, predictions, normalized, stats, log_cost, &
                          log_lambda, log_step, log_params, info, code, message, note)
    end subroutine api_deck_handle_fit

    !> The rows of rung k's fit of the ladder of `handle` as the measurement
    !! chain's treatments judged them (outputs as beamid_api_estimation
    !! api_ladder_handle_rows).
    subroutine api_deck_handle_rows(handle, k, nrow, weights, sigma_used, sigma_sd, flagged, &
                                    has, code, message)
        integer(c_int), intent(in) :: handle, k, nrow
        real(c_double), intent(out) :: weights(nrow), sigma_used(nrow), sigma_sd(nrow)
        integer(c_int), intent(out) :: flagged(nrow), has, code
        character(len=256), intent(out) :: message
        if (.not. handle_ok(handle, code, message)) return
        call rung_rows_out(runs(handle)%deck%lad, k, nrow, whose(handle), weights, sigma_used, &
                           sigma_sd, flagged, has, code, message)
    end subroutine api_deck_handle_rows

    !> The diagnosis of rung k of the ladder of `handle` (outputs as
    !! beamid_api_estimation api_problem_diagnose).
    subroutine api_deck_handle_diag(handle, k, nparams, ncand, ncandp, cstats, pstats, &
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
        if (.not. handle_ok(handle, code, message)) return
        call rung_diag_out(runs(handle)%deck%lad, k, nparams, ncand, ncandp, whose(handle), &
                           cstats, pstats, refit_params, ranking, cosine, dstats, refit_start, &
                           sep_t, mstats, mesh_params, kept, notes, code, message)
    end subroutine api_deck_handle_diag

    !> The deck of handle, as refusals name its ladder.
    function whose(handle) result(text)
        integer(c_int), intent(in) :: handle
        character(len=:), allocatable :: text
        text = 'the deck of handle '//fmt_int(int(handle))
    end function whose

    !> Write the files of the deck of `handle` from the ladder (or the
    !! stages) api_deck_handle_start started and api_deck_handle_step ended
    !! (beamid_deck_run deck_run_write: all or none, the bytes beamid-batch
    !! writes); `output`: the output prefix (blank: the deck's; beamid demo
    !! writes its decks' files elsewhere); `written`: the files, one per line.
    subroutine api_deck_handle_write(handle, output, written, summary, code, message)
        integer(c_int), intent(in) :: handle
        character(len=*), intent(in) :: output
        character(len=65536), intent(out) :: written, message
        !> the summary line beamid-batch prints (run_task)
        character(len=4096), intent(out) :: summary
        integer(c_int), intent(out) :: code
        type(status_t) :: stat
        character(len=:), allocatable :: files, line
        written = ''
        summary = ''
        if (.not. handle_ok(handle, code, message)) return
        call deck_run_write(runs(handle)%deck, trim(output), files, line, stat)
        if (stat%code == STATUS_OK) call put_text(files, written)
        if (stat%code == STATUS_OK) summary = line
        call status_out(stat, code, message)
    end subroutine api_deck_handle_write

    !> The size of a measurement table of the deck of `handle`: stage 0 the
    !! deck's data file, stage k the k-th stage's of an identify deck.
    subroutine api_deck_handle_data_size(handle, stage, nrow, code, message)
        integer(c_int), intent(in) :: handle, stage
        integer(c_int), intent(out) :: nrow, code
        character(len=65536), intent(out) :: message
        nrow = 0
        if (.not. handle_ok(handle, code, message)) return
        if (.not. stage_ok(handle, stage, code, message)) return
        if (stage == 0) then
            if (allocated(runs(handle)%deck%deck%data%value)) &
                nrow = int(size(runs(handle)%deck%deck%data%value), c_int)
        else
            nrow = int(size(runs(handle)%deck%deck%stages(stage)%data%value), c_int)
        end if
    end subroutine api_deck_handle_data_size

    !> Is stage 0 or a stage of the deck of handle? (else ERR_INPUT)
    logical function stage_ok(handle, stage, code, message)
        integer(c_int), intent(in) :: handle, stage
        integer(c_int), intent(out) :: code
        character(len=*), intent(out) :: message
        type(status_t) :: stat
        integer :: n
        n = 0
        if (allocated(runs(handle)%deck%deck%stages)) n = size(runs(handle)%deck%deck%stages)
        stage_ok = stage >= 0 .and. stage <= n
        if (.not. stage_ok) call set_status(stat, ERR_INPUT, 'stage', fmt_int(int(stage))// &
                                            ', expected 0..'//fmt_int(n))
        call status_out(stat, code, message)
    end function stage_ok

    !> The rows of a measurement table of the deck of `handle` (stage as
    !! api_deck_handle_data_size; outputs as api_measurements_read).
    subroutine api_deck_handle_data(handle, stage, nrow, t, value, sigma, line, quantity, &
                                    exp_index, names, qnames, code, message)
        integer(c_int), intent(in) :: handle, stage
        integer(c_int), intent(in) :: nrow
        real(c_double), intent(out) :: t(nrow), value(nrow), sigma(nrow)
        integer(c_int), intent(out) :: line(nrow), quantity(nrow), exp_index(nrow)
        character(len=65536), intent(out) :: names, qnames
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        names = ''
        qnames = ''
        if (.not. handle_ok(handle, code, message)) return
        if (.not. stage_ok(handle, stage, code, message)) return
        if (stage == 0) then
            call copy_rows(runs(handle)%deck%deck%data, runs(handle)%deck%deck%data_path, nrow, t, &
                           value, sigma, line, quantity, exp_index, names, qnames, code, message)
        else
            associate (s => runs(handle)%deck%deck%stages(stage))
                call copy_rows(s%data, s%data_path, nrow, t, value, sigma, line, quantity, &
                               exp_index, names, qnames, code, message)
            end associate
        end if
    end subroutine api_deck_handle_data

    !> Rows of a measurement CSV (after validation) and the longest name.
    subroutine api_measurements_size(path, nrow, code, message)
        character(len=*), intent(in) :: path
        integer(c_int), intent(out) :: nrow, code
        character(len=65536), intent(out) :: message
        type(measurements_t) :: data
        type(status_t) :: stat
        call read_measurements(trim(path), data, stat)
        call status_out(stat, code, message)
        if (stat%code == STATUS_OK) nrow = int(size(data%value), c_int)
    end subroutine api_measurements_size

    !> The rows of a measurement CSV: t, value, sigma, source line, the
    !! index of each row's observation into `qnames` (the distinct
    !! observation names, one per line, first use order, as
    !! beamid_observations writes them), and the index of each row's
    !! experiment into `names` (the distinct experiment names, likewise).
    subroutine api_measurements_read(path, nrow, t, value, sigma, line, quantity, exp_index, &
                                     names, qnames, code, message)
        character(len=*), intent(in) :: path
        integer(c_int), intent(in) :: nrow
        real(c_double), intent(out) :: t(nrow), value(nrow), sigma(nrow)
        integer(c_int), intent(out) :: line(nrow), quantity(nrow), exp_index(nrow)
        character(len=65536), intent(out) :: names, qnames
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        type(measurements_t) :: data
        type(status_t) :: stat
        names = ''
        qnames = ''
        call read_measurements(trim(path), data, stat)
        call status_out(stat, code, message)
        if (stat%code /= STATUS_OK) return
        call copy_rows(data, trim(path), nrow, t, value, sigma, line, quantity, exp_index, &
                       names, qnames, code, message)
    end subroutine api_measurements_read

    !> The outputs of api_measurements_read from the rows of `data` (read
    !! from `path`, named in messages).
    subroutine copy_rows(data, path, nrow, t, value, sigma, line, quantity, exp_index, names, &
                         qnames, code, message)
        type(measurements_t), intent(in) :: data
        character(len=*), intent(in) :: path
        integer(c_int), intent(in) :: nrow
        real(c_double), intent(out) :: t(nrow), value(nrow), sigma(nrow)
        integer(c_int), intent(out) :: line(nrow), quantity(nrow), exp_index(nrow)
        character(len=65536), intent(out) :: names, qnames
        integer(c_int), intent(out) :: code
        character(len=65536), intent(out) :: message
        character(len=:), allocatable :: joined
        character(len=:), allocatable :: seen(:)
        integer :: i, j, k, n
        names = ''
        qnames = ''
        code = 0
        message = ''
        n = 0
        if (allocated(data%value)) n = size(data%value)
        if (n /= nrow) then
            code = int(ERR_INPUT, c_int)
            message = path//': nrow = '//fmt_int(int(nrow))//', expected '// &
                      fmt_int(n)//' (the rows read)'
            return
        end if
        if (n == 0) return
        t = data%t
        value = data%value
        sigma = data%sigma
        line = int(data%line, c_int)
        quantity = int(obs_groups(data%obs), c_int)
        qnames = ''
        joined = ''
        do i = 1, nrow
            if (quantity(i) /= i) cycle
            joined = joined//obs_label(data%obs(i))//new_line('a')
        end do
        ! renumber the groups 1, 2, ... in first-use order
        n = 0
        do i = 1, nrow
            if (quantity(i) == i) then
                n = n + 1
                quantity(i) = int(n, c_int)
            else
                quantity(i) = quantity(quantity(i))
            end if
        end do
        if (len(joined) > TEXT_LEN) then
            code = int(ERR_INPUT, c_int)
            message = path//': the observation names take over '//fmt_int(TEXT_LEN)// &
                      ' characters'
            return
        end if
        qnames = joined
        allocate (character(len=len(data%experiment)) :: seen(nrow))
        n = 0
        joined = ''
        do i = 1, nrow
            k = 0
            do j = 1, n
                if (seen(j) == data%experiment(i)) then
                    k = j
                    exit
                end if
            end do
            if (k == 0) then
                n = n + 1
                seen(n) = data%experiment(i)
                k = n
                joined = joined//trim(data%experiment(i))//new_line('a')
            end if
            exp_index(i) = int(k, c_int)
        end do
        if (len(joined) > TEXT_LEN) then
            code = int(ERR_INPUT, c_int)
            message = path//': the experiment names take over '//fmt_int(TEXT_LEN)// &
                      ' characters'
            return
        end if
        names = joined
    end subroutine copy_rows

    !> Names of the observation kinds 1..n (beamid_observations), one per line.
    subroutine api_quantity_labels(text)
        character(len=4096), intent(out) :: text
        character(len=:), allocatable :: joined
        integer :: q
        joined = ''
        do q = 1, NKIND
            joined = joined//kind_label(q)//new_line('a')
        end do
        text = joined
    end subroutine api_quantity_labels

    !> The observation table of beamid_observations, one kind per line:
    !! name;unit;families;locus;needs;sigma;probe_static;probe_release;twin;rate;about.
    subroutine api_observation_table(text)
        character(len=16384), intent(out) :: text
        text = kind_table_text()
    end subroutine api_observation_table

    !> Parse an observation name (beamid_observations parse_observation):
    !! its kind code, beam and arc length s (a station), mode, and the
    !! canonical name; code ERR_INPUT with what is wrong.
    subroutine api_observation_parse(name, kind, beam, s, mode, label, code, message)
        character(len=*), intent(in) :: name
        integer(c_int), intent(out) :: kind, beam, mode
        real(c_double), intent(out) :: s
        character(len=256), intent(out) :: label
        integer(c_int), intent(out) :: code
        character(len=256), intent(out) :: message
        type(observation_t) :: o
        type(status_t) :: stat
        character(len=:), allocatable :: why
        call parse_observation(name, o, why)
        if (len(why) > 0) call set_status(stat, ERR_INPUT, 'observation', why)
        call status_out(stat, code, message)
        kind = int(o%kind, c_int)
        beam = int(o%beam, c_int)
        mode = int(o%mode, c_int)
        s = real(o%s, c_double)
        label = ''
        if (len(why) == 0) label = obs_label(o)
    end subroutine api_observation_parse
end module beamid_api_deck
