!> The binding's copies of library results into the output arrays of its
!! entries (no f2py entry here: a module of the core library that the f2py
!! modules of fortran/api share): a fit's outputs (copy_fit), a diagnosis'
!! (copy_diag) and a ladder's rungs (rung_out, rung_fit_out,
!! rung_diag_out: the caller's sizes checked against the ladder), for the
!! entries on a problem (beamid_api_estimation) and on a deck's run
!! (beamid_api_deck).
module beamid_api_marshal
    use, intrinsic :: iso_c_binding, only: c_int, c_double
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, status_out, set_status, fmt_int, ERR_INPUT
    use beamid_estimation, only: fit_result_t
    use beamid_ladder, only: cand_set_t, diag_out_t, ladder_t
    implicit none
    private

    public :: copy_fit, copy_diag, rung_out, rung_fit_out, rung_diag_out, rung_rows_out, &
              cand_params_size

contains

    !> The outputs of a fit entry from a fit result: stats = chi2, chi2_prior,
    !! cond, dof, rank, iterations, converged, nlog (names: api_code_names 5);
    !! the log arrays hold nlog + 1 entries (entry 1 = start; the rest zero,
    !! as f2py allocates them).
    subroutine copy_fit(res, params, sigmas, cov, corr, flags, predictions, normalized, stats, &
                        log_cost, log_lambda, log_step, log_params)
        type(fit_result_t), intent(in) :: res
        real(c_double), intent(out) :: params(:), sigmas(:), cov(:, :), corr(:, :)
        integer(c_int), intent(out) :: flags(:)
        real(c_double), intent(out) :: predictions(:), normalized(:), stats(8)
        real(c_double), intent(inout) :: log_cost(:), log_lambda(:), log_step(:), &
                                         log_params(:, :)
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

    !> The outputs of a diagnosis (zero when `ok` is false): cstats 18 values
    !! per candidate, pstats 6 per candidate parameter, dstats 6 (names:
    !! api_code_names tables 6-8); candidate state 4 (CAND_NOT_SEEN) for
    !! effects the data rows do not see; refit_start(c) the start the refit
    !! kept (START_*, 0: none); sep_t(c) the time of the probe row separating
    !! rival c from the verdict; mstats the mesh test (table 9), mesh_params
    !! its refined refit's parameters (else `params`); kept(k) 1: the
    !! candidate parameter was tested, 0: left at null (not needed or not
    !! determined), 2: left at null although about as good alone as the
    !! member tested; `notes` one line per candidate (what the refit starts
    !! gave, newline-separated).
    subroutine copy_diag(dg, cs, ok, params, cstats, pstats, refit_params, ranking, cosine, &
                         dstats, refit_start, sep_t, mstats, mesh_params, kept, notes)
        type(diag_out_t), intent(in) :: dg
        type(cand_set_t), intent(in) :: cs
        logical, intent(in) :: ok
        real(dp), intent(in) :: params(:)
        real(c_double), intent(out) :: cstats(:, :), pstats(:, :), refit_params(:, :)
        real(c_double), intent(out) :: cosine(:, :), dstats(:), sep_t(:), mstats(:)
        real(c_double), intent(out) :: mesh_params(:)
        integer(c_int), intent(out) :: ranking(:), refit_start(:), kept(:)
        character(len=*), intent(out) :: notes
        character(len=:), allocatable :: text
        integer :: c, k, j, nf, r, u

        mesh_params = params
        notes = ''
        if (.not. ok) return
        nf = 0       ! a rung that ended at its fit (fit, compare decks): not diagnosed
        if (allocated(dg%base%free)) nf = size(dg%base%free)
        text = ''
        k = 0
        do c = 1, size(cs%cands)
            associate (cr => dg%diag%cand(c))
                r = cr%separating_row
                cstats(:, c) = [real(cr%state, dp), cr%score%drop, cr%score%p_value, &
                                real(cr%score%dof, dp), b2r(cr%score%physical), &
                                b2r(cr%score%identifiable), b2r(cr%refit_done), &
                                b2r(cr%refit_ok), cr%lr_drop, cr%lr_p, b2r(cr%significant), &
                                b2r(cr%acceptable), b2r(cr%rival), cr%separation, &
                                0.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]
                ! (merge() would index the probe rows, possibly none, even for r = 0)
                if (r > 0) then
                    cstats(15, c) = real(dg%pexp(r), dp)
                    cstats(16, c) = real(dg%pq(r), dp)
                    sep_t(c) = dg%pt(r)
                end if
                if (cr%refit_ok) then
                    cstats(17, c) = cr%refit%chi2
                    cstats(18, c) = cr%refit%chi2_prior
                    refit_params(:, c) = cr%refit%params
                end if
                refit_start(c) = int(cr%info%start, c_int)
                if (c > 1) text = text//new_line('a')
                if (cr%refit_done .and. allocated(cr%info%note)) text = text//cr%info%note
                do j = 1, size(cs%cands(c)%params)
                    k = k + 1
                    ! position of this parameter in the block as tested
                    u = findloc(dg%used(c)%params, cs%cands(c)%params(j), 1)
                    if (u == 0 .and. any(dg%ambiguous == cs%cands(c)%params(j))) kept(k) = 2
                    if (u == 0) cycle
                    kept(k) = 1
                    if (allocated(cr%score%estimate)) then
                        pstats(1:3, k) = [cr%score%estimate(u), cr%score%sigma(u), &
                                          b2r(cr%score%active(u))]
                    end if
                    if (cr%refit_ok) then
                        pstats(4:6, k) = [cr%refit%params(dg%used(c)%params(u)), &
                                          cr%refit%sigmas(nf + u), &
                                          real(cr%refit%flags(nf + u), dp)]
                    end if
                end do
            end associate
        end do
        notes = text
        ranking = int(dg%diag%ranking, c_int)
        cosine = dg%diag%cosine
        dstats = [real(dg%diag%verdict, dp), real(dg%diag%ntested, dp), dg%diag%alpha_each, &
                  dg%base%chi2, dg%base%chi2_prior, real(dg%base%dof, dp)]
        associate (m => dg%mesh)
            mstats = [b2r(m%done), b2r(m%ok), real(m%nepb, dp), real(m%recommended, dp), &
                      m%chi2, m%drop, m%p_value, m%max_change, real(m%max_row, dp), &
                      b2r(m%significant)]
            if (allocated(m%params)) mesh_params = m%params
        end associate
    contains
        pure real(dp) function b2r(flag)
            logical, intent(in) :: flag
            b2r = merge(1.0_dp, 0.0_dp, flag)
        end function b2r
    end subroutine copy_diag

    !> Rung k of lad: effect ('start', the number of the candidate added, or
    !! 'mesh (N elements per beam)'), info = [free parameters, elements per
    !! beam of the releases (0: as given), the start the verdict's refit kept
    !! (START_*), data rows, the fits' iteration limit], the free parameters,
    !! those the rung switched on and those it set back (index lists, zeros
    !! after), where its fit started and the nominal model of its refits.
    !! `whose` names the ladder in refusals.
    subroutine rung_out(lad, k, nparams, whose, info, free_idx, added, removed, start, nominal, &
                        effect, code, message)
        type(ladder_t), intent(in) :: lad
        integer(c_int), intent(in) :: k, nparams
        character(len=*), intent(in) :: whose
        integer(c_int), intent(out) :: info(5), free_idx(nparams), added(nparams)
        integer(c_int), intent(out) :: removed(nparams)
        real(c_double), intent(out) :: start(nparams), nominal(nparams)
        character(len=*), intent(out) :: effect
        integer(c_int), intent(out) :: code
        character(len=*), intent(out) :: message
        effect = ''
        if (.not. rung_ok(lad, k, nparams, whose, code, message)) return
        associate (r => lad%rungs(k))
            info = [size(r%fit%free), r%nepb, r%refit_start, size(lad%pb%y), lad%pb%max_iter]
            free_idx(:size(r%fit%free)) = r%fit%free
            added(:size(r%params)) = r%params
            removed(:size(r%removed)) = r%removed
            start = r%start
            nominal = r%nominal
            effect = r%effect
        end associate
    end subroutine rung_out

    !> The fit of rung k of lad (outputs as api_fit_effect; copy_fit).
    subroutine rung_fit_out(lad, k, nparams, nfree, nrow, whose, params, sigmas, cov, corr, &
                            flags, predictions, normalized, stats, log_cost, log_lambda, &
                            log_step, log_params, info, code, message, note)
        type(ladder_t), intent(in) :: lad
        integer(c_int), intent(in) :: k, nparams, nfree, nrow
        character(len=*), intent(in) :: whose
        real(c_double), intent(out) :: params(:), sigmas(:), cov(:, :), corr(:, :)
        real(c_double), intent(out) :: predictions(:), normalized(:), stats(8)
        integer(c_int), intent(out) :: flags(:), info(2)
        real(c_double), intent(inout) :: log_cost(:), log_lambda(:), log_step(:), &
                                         log_params(:, :)
        integer(c_int), intent(out) :: code
        character(len=*), intent(out) :: message, note
        type(status_t) :: stat
        note = ''
        if (.not. rung_ok(lad, k, nparams, whose, code, message)) return
        associate (f => lad%rungs(k)%fit)
            if (nfree /= size(f%free) .or. nrow /= size(f%predictions)) then
                call set_status(stat, ERR_INPUT, 'ladder', 'nfree = '//fmt_int(int(nfree))// &
                    ', nrow = '//fmt_int(int(nrow))//', expected '//fmt_int(size(f%free))// &
                    ' and '//fmt_int(size(f%predictions))//' (rung '//fmt_int(int(k))// &
                    ' of '//whose//')')
                call status_out(stat, code, message)
                return
            end if
            info(1) = int(f%stop, c_int)
            if (allocated(f%note)) note = f%note
            if (allocated(f%note)) message = f%note
            call copy_fit(f, params, sigmas, cov, corr, flags, predictions, normalized, stats, &
                          log_cost, log_lambda, log_step, log_params)
        end associate
    end subroutine rung_fit_out

    !> The diagnosis of rung k of lad (outputs as api_problem_diagnose;
    !! copy_diag), zeros after a refusal.
    subroutine rung_diag_out(lad, k, nparams, ncand, ncandp, whose, cstats, pstats, &
                             refit_params, ranking, cosine, dstats, refit_start, sep_t, mstats, &
                             mesh_params, kept, notes, code, message)
        type(ladder_t), intent(in) :: lad
        integer(c_int), intent(in) :: k, nparams, ncand, ncandp
        character(len=*), intent(in) :: whose
        real(c_double), intent(out) :: cstats(:, :), pstats(:, :), refit_params(:, :)
        real(c_double), intent(out) :: cosine(:, :), dstats(:), sep_t(:), mstats(:)
        real(c_double), intent(out) :: mesh_params(:)
        integer(c_int), intent(out) :: ranking(:), refit_start(:), kept(:)
        character(len=*), intent(out) :: notes
        integer(c_int), intent(out) :: code
        character(len=*), intent(out) :: message
        type(diag_out_t) :: none
        type(status_t) :: stat
        if (rung_ok(lad, k, nparams, whose, code, message)) then
            if (size(lad%cs%cands) == ncand .and. ncandp == cand_params_size(lad%cs)) then
                call copy_diag(lad%rungs(k)%dg, lad%cs, .true., lad%rungs(k)%fit%params, cstats, &
                               pstats, refit_params, ranking, cosine, dstats, refit_start, sep_t, &
                               mstats, mesh_params, kept, notes)
                return
            end if
            call set_status(stat, ERR_INPUT, 'ladder', 'ncand = '//fmt_int(int(ncand))// &
                            ', ncandp = '//fmt_int(int(ncandp))//', expected '// &
                            fmt_int(size(lad%cs%cands))//' candidates of '// &
                            fmt_int(cand_params_size(lad%cs))//' parameters ('//whose//')')
            call status_out(stat, code, message)
        end if
        call copy_diag(none, lad%cs, .false., spread(0.0_dp, 1, int(nparams)), cstats, &
                       pstats, refit_params, ranking, cosine, dstats, refit_start, sep_t, mstats, &
                       mesh_params, kept, notes)
    end subroutine rung_diag_out

    !> The rows of rung k's fit of lad as the measurement chain's treatments
    !! judged them (beamid_chain_fit): per row its last weight, the sigma it
    !! was judged with, that sigma's standard deviation and 1 for a gross
    !! error; has = 0 for a plain fit (nothing set).
    subroutine rung_rows_out(lad, k, nrow, whose, weights, sigma_used, sigma_sd, flagged, has, &
                             code, message)
        type(ladder_t), intent(in) :: lad
        integer(c_int), intent(in) :: k, nrow
        character(len=*), intent(in) :: whose
        real(c_double), intent(out) :: weights(:), sigma_used(:), sigma_sd(:)
        integer(c_int), intent(out) :: flagged(:), has, code
        character(len=*), intent(out) :: message
        type(status_t) :: stat
        has = 0
        weights = 1.0_c_double
        sigma_used = 0.0_c_double
        sigma_sd = 0.0_c_double
        flagged = 0
        if (k >= 1 .and. k <= lad%n) then
            if (.not. rung_ok(lad, k, int(size(lad%rungs(k)%start), c_int), whose, code, &
                              message)) return
        else
            if (.not. rung_ok(lad, k, 0_c_int, whose, code, message)) return
        end if
        associate (f => lad%rungs(k)%fit)
            if (nrow /= size(f%predictions)) then
                call set_status(stat, ERR_INPUT, 'ladder', 'nrow = '//fmt_int(int(nrow))// &
                                ', expected '//fmt_int(size(f%predictions))//' (rung '// &
                                fmt_int(int(k))//' of '//whose//')')
                call status_out(stat, code, message)
                return
            end if
            if (.not. allocated(f%row_sigma)) return
            has = 1
            weights = f%row_weight
            sigma_used = f%row_sigma
            sigma_sd = f%row_sigma_sd
            flagged = merge(1_c_int, 0_c_int, f%row_gross)
        end associate
    end subroutine rung_rows_out

    !> Is k a rung of lad, of nparams parameters? (else ERR_INPUT naming k
    !! or nparams; `whose` names the ladder)
    logical function rung_ok(lad, k, nparams, whose, code, message)
        type(ladder_t), intent(in) :: lad
        integer(c_int), intent(in) :: k, nparams
        character(len=*), intent(in) :: whose
        integer(c_int), intent(out) :: code
        character(len=*), intent(out) :: message
        type(status_t) :: stat
        rung_ok = k >= 1 .and. k <= lad%n
        if (.not. rung_ok) then
            call set_status(stat, ERR_INPUT, 'ladder', 'rung '//fmt_int(int(k))// &
                            ', expected 1..'//fmt_int(lad%n)//' (start and step a ladder first)')
        else if (nparams /= size(lad%rungs(k)%start)) then
            rung_ok = .false.
            call set_status(stat, ERR_INPUT, 'ladder', 'nparams = '//fmt_int(int(nparams))// &
                            ', expected '//fmt_int(size(lad%rungs(k)%start))// &
                            ' (the parameters of '//whose//')')
        end if
        call status_out(stat, code, message)
    end function rung_ok

    !> The parameters of all candidates of cs (ncandp of the diagnosis entries).
    pure integer function cand_params_size(cs)
        type(cand_set_t), intent(in) :: cs
        integer :: c
        cand_params_size = 0
        do c = 1, size(cs%cands)
            cand_params_size = cand_params_size + size(cs%cands(c)%params)
        end do
    end function cand_params_size

end module beamid_api_marshal
