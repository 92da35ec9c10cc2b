!> The inverse problem's orchestration: the diagnosis of a fitted model
!! on a problem of any families (the problem itself, its families and the
!! measurement chain are beamid_problem; this module re-exports them, so
!! callers of the old single module keep working).
module beamid_inverse
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK
    use beamid_estimation, only: residual_model_t, lsq_problem_t, fit_options_t, &
                                 fit_result_t, candidate_t, diagnose_options_t, diagnosis_t, &
                                 fit_at, diagnose
    use beamid_problem, only: inverse_problem_t, problem_t, inverse_problem_init, inverse_lsq, &
                              chain_layout, EXP_TIP, EXP_WIRE, EXP_RELEASE, EV_FX, EV_FY, &
                              EV_MOMENT, EV_WIRE_LENGTH, EV_NEPB, EV_GAIN, EV_METHOD, EV_LAW, &
                              EV_RTOL, EV_DT, EV_VSLIP, EV_FD, EV_T0, EV_BIAS, EV_SCALE, &
                              EV_LOSS, EV_BURNIN, EV_SIGEST, NEXPVAL, NU_T0, NU_BIAS, NU_SCALE, &
                              NU_V0, EV_V0, MAX_CHANNEL_BITS, experiment_spec_t
    implicit none
    private

    public :: inverse_problem_t, problem_t, inverse_problem_init, inverse_lsq, inverse_diagnose
    public :: chain_layout, experiment_spec_t
    public :: EXP_TIP, EXP_WIRE, EXP_RELEASE, EV_FX, EV_FY, EV_MOMENT, EV_WIRE_LENGTH, EV_NEPB, &
              EV_GAIN, EV_METHOD, EV_LAW, EV_RTOL, EV_DT, EV_VSLIP, EV_FD, EV_T0, EV_BIAS, &
              EV_SCALE, EV_LOSS, EV_BURNIN, EV_SIGEST, NEXPVAL, NU_T0, NU_BIAS, NU_SCALE, &
              NU_V0, EV_V0, MAX_CHANNEL_BITS

contains

    !> The diagnosis of a fitted model (the orchestration both fronts call):
    !! the base fit evaluated at params0 (the estimates, not refitted), score
    !! tests of every candidate, refits of the leading ones from the
    !! first-order estimate, from params0 with the effect at null, from
    !! `nominal` (the user's starting model) and by continuation, and the
    !! probe rows that separate rivals: those of the first family that
    !! proposes any (the static family: every static experiment and every
    !! quantity it can measure, probe_rows). pexp, pq: experiment number and
    !! quantity of each probe row (diag%cand(c)%separating_row indexes them).
    subroutine inverse_diagnose(self, lp, params0, nominal, free, cands, fopts, dopts, base, &
                                diag, pexp, pq, stat)
        type(inverse_problem_t), intent(inout) :: self
        type(lsq_problem_t), intent(in) :: lp
        real(dp), intent(in) :: params0(:), nominal(:)
        integer, intent(in) :: free(:)
        type(candidate_t), intent(in) :: cands(:)
        type(fit_options_t), intent(in) :: fopts
        type(diagnose_options_t), intent(in) :: dopts
        type(fit_result_t), intent(out) :: base
        type(diagnosis_t), intent(out) :: diag
        integer, allocatable, intent(out) :: pexp(:), pq(:)
        type(status_t), intent(inout) :: stat
        class(residual_model_t), allocatable :: probe
        real(dp), allocatable :: psig(:)
        integer, allocatable :: plocal(:)
        integer :: f
        allocate (pexp(0), pq(0))
        call fit_at(self, lp, params0, free, fopts, base, stat)
        if (stat%code /= STATUS_OK) return
        ! the first family that proposes probe rows and a model of them (the
        ! static family: every experiment, every quantity it can measure)
        do f = 1, size(self%fams)
            associate (fam => self%fams(f)%item)
                call fam%probe(lp%sigma(fam%rows), plocal, pq, psig)
                call fam%probe_model(plocal, pq, self%tol, probe, stat)
                if (stat%code /= STATUS_OK) return
                if (.not. allocated(probe)) cycle
                pexp = fam%exp_ids(plocal)
                call diagnose(self, lp, base, cands, fopts, dopts, diag, stat, probe, psig, &
                              nominal)
                return
            end associate
        end do
        pq = [integer ::]
        call diagnose(self, lp, base, cands, fopts, dopts, diag, stat, nominal=nominal)
    end subroutine inverse_diagnose
end module beamid_inverse
