!> Monte Carlo replicates of a fit (beamid.consistency, issue 25's speed
!! rule): the same experiments, rows, sigmas, free parameters and a priori
!! sigmas refitted on many data vectors, one call for all of them.
!!
!! Each replicate is exactly the fit the one-fit entry would make of its
!! data (api_fit_effect without an effect block): its inverse problem and
!! least-squares problem are built afresh from the same arrays
!! (problem_lsq_from_arrays) with the replicate's row values and a priori
!! means, then fitted from params0 (fit_least_squares). Building afresh keeps
!! a replicate independent of the ones before it (a family's solver state,
!! the rough-model switch), so its numbers are those of a fit of its data
!! alone; what the loop saves is the front's per-fit work (the argument
!! checks, the problem's arrays, the marshalling and the result's assembly).
!!
!! A replicate whose fit fails keeps its status code (out%code, STATUS_OK
!! when it ended: converged, stalled or with a flagged parameter, see
!! out%stop); the front refits such a replicate through the one-fit path to
!! report its message. The routine itself returns an input error only for
!! arrays whose shapes disagree.
module beamid_replicates
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, set_status, STATUS_OK, ERR_INPUT, fmt_int
    use beamid_estimation, only: fit_options_t, fit_result_t, fit_least_squares, lsq_problem_t
    use beamid_problem, only: inverse_problem_t, problem_lsq_from_arrays, experiment_spec_t
    use beamid_dynamic_experiments, only: exp_histories_t
    implicit none
    private

    public :: fit_replicates

    !> The columns of out%stats, as the one-fit entry's stats (chi2,
    !! chi2_prior, cond, dof, rank, iterations, converged, nlog).
    integer, parameter, public :: NREP_STATS = 8

    !> What each replicate's fit gave (column r: replicate r).
    type, public :: replicate_out_t
        real(dp), allocatable :: params(:, :)   !< (nparams, nrep) the full parameter vector
        real(dp), allocatable :: sigmas(:, :)   !< (nfree, nrep)
        integer, allocatable :: flags(:, :)     !< (nfree, nrep) FLAG_* of beamid_estimation
        real(dp), allocatable :: stats(:, :)    !< (NREP_STATS, nrep)
        integer, allocatable :: stop(:)         !< (nrep) how the fit ended (STOP_*)
        integer, allocatable :: code(:)         !< (nrep) the fit's status code
    end type replicate_out_t

contains

    !> Fit replicate r = 1..size(ys, 2) of the problem: rows y = ys(:, r),
    !! a priori means means(:, r) (prior's own means are not used; its
    !! indices and sigmas are), everything else as the one-fit entry's
    !! set-up from the same arrays (problem_lsq_from_arrays, independent a
    !! priori information), fitted from params0 with `opts`.
    subroutine fit_replicates(nbeams, exp_kind, specs, row_exp, row_t, row_q, obs_kind, &
                              obs_beam, obs_s, tol, sigma, prior, hist, params0, free, opts, &
                              ys, means, out, stat)
        integer, intent(in) :: nbeams, exp_kind(:), row_exp(:), row_q(:)
        integer, intent(in) :: obs_kind(:), obs_beam(:), free(:)
        type(experiment_spec_t), intent(in) :: specs(:)
        real(dp), intent(in) :: row_t(:), obs_s(:), tol, sigma(:)
        real(dp), intent(in) :: prior(:, :), params0(:), ys(:, :), means(:, :)
        type(exp_histories_t), intent(in) :: hist
        type(fit_options_t), intent(in) :: opts
        type(replicate_out_t), intent(out) :: out
        type(status_t), intent(inout) :: stat
        character(len=*), parameter :: where = 'replicates'
        real(dp), allocatable :: pr(:, :)
        real(dp) :: no_cov(0)
        integer :: r, nrep, nfree

        nrep = size(ys, 2)
        nfree = size(free)
        if (size(ys, 1) /= size(row_exp) .or. size(sigma) /= size(row_exp)) then
            call set_status(stat, ERR_INPUT, where, 'row values '//fmt_int(size(ys, 1))// &
                            ' and sigmas '//fmt_int(size(sigma))//' per replicate, expected '// &
                            fmt_int(size(row_exp))//' (one per data row)')
            return
        end if
        if (size(means, 1) /= size(prior, 2) .or. size(means, 2) /= nrep) then
            call set_status(stat, ERR_INPUT, where, 'a priori means '//fmt_int(size(means, 1))// &
                            ' x '//fmt_int(size(means, 2))//', expected '// &
                            fmt_int(size(prior, 2))//' x '//fmt_int(nrep)// &
                            ' (one per a priori entry and replicate)')
            return
        end if
        allocate (out%params(size(params0), nrep), out%sigmas(nfree, nrep), &
                  out%stats(NREP_STATS, nrep), source=0.0_dp)
        allocate (out%flags(nfree, nrep), out%stop(nrep), out%code(nrep), source=0)
        pr = prior
        do r = 1, nrep
            pr(2, :) = means(:, r)
            call one(r)
        end do
    contains
        !> Replicate r's set-up and fit (its own problem, status and result).
        subroutine one(r)
            integer, intent(in) :: r
            type(inverse_problem_t) :: model
            type(lsq_problem_t) :: lp
            type(fit_result_t) :: res
            type(status_t) :: rs
            call problem_lsq_from_arrays(nbeams, exp_kind, specs, row_exp, row_t, row_q, &
                                         obs_kind, obs_beam, obs_s, tol, ys(:, r), sigma, pr, &
                                         no_cov, model, lp, rs, hist)
            if (rs%code == STATUS_OK) call fit_least_squares(model, lp, params0, free, opts, res, rs)
            out%code(r) = rs%code
            out%params(:, r) = params0
            if (.not. allocated(res%params)) return
            out%stop(r) = res%stop
            out%params(:, r) = res%params
            out%sigmas(:, r) = res%sigmas
            out%flags(:, r) = res%flags
            out%stats(:, r) = [res%chi2, res%chi2_prior, res%cond, real(res%dof, dp), &
                               real(res%rank, dp), real(res%iterations, dp), &
                               merge(1.0_dp, 0.0_dp, res%converged), real(res%nlog, dp)]
        end subroutine one
    end subroutine fit_replicates

end module beamid_replicates
