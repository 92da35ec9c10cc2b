!> Seconds per element of one banded tangent assembly (internal force and
!! K_T, beamid_fe_assembly fe_tangent) on the PACE arm at a fixed bent
!! state, best of three runs of nrep assemblies (`make bench` through
!! benchmarks/bench_fe.py; `meson test --benchmark`).
!!
!! Usage: bench_fe_tangent [elements_per_beam [nrep]] (defaults 256, 200).
program bench_fe_tangent
    use, intrinsic :: iso_fortran_env, only: int64, error_unit
    use beamid_kinds, only: dp
    use beamid_status, only: status_t, STATUS_OK
    use beamid_model, only: chain_t, chain_from_vector
    use beamid_presets, only: preset_params
    use beamid_fe_assembly, only: fe_mesh_t, fe_mesh_build, fe_band_rows, fe_tangent
    implicit none
    type(chain_t) :: chain
    type(fe_mesh_t) :: mesh
    type(status_t) :: stat
    real(dp), allocatable :: params(:), q(:), f(:), kb(:, :)
    real(dp) :: best, seconds
    integer(int64) :: t0, t1, rate
    integer :: nb, nepb, nrep, i, run
    character(len=32) :: arg

    nepb = 256
    nrep = 200
    if (command_argument_count() >= 1) then
        call get_command_argument(1, arg)
        read (arg, *) nepb
    end if
    if (command_argument_count() >= 2) then
        call get_command_argument(2, arg)
        read (arg, *) nrep
    end if
    call preset_params('pace', nb, params, stat)
    if (stat%code == STATUS_OK) call chain_from_vector(nb, params, chain, stat)
    if (stat%code == STATUS_OK) call fe_mesh_build(chain, nepb, mesh, stat)
    if (stat%code /= STATUS_OK .or. nrep < 1) then
        write (error_unit, '(a)') 'bench_fe_tangent: '//trim(stat%message)
        error stop 2
    end if
    allocate (q(mesh%nfree), f(mesh%nfree), kb(fe_band_rows(mesh), mesh%nfree))
    best = huge(1.0_dp)
    do run = 1, 3
        do i = 1, mesh%nfree
            q(i) = 1.0e-2_dp*sin(real(i, dp))
        end do
        call system_clock(t0, rate)
        do i = 1, nrep
            call fe_tangent(mesh, q, f, kb)
            q(1) = q(1) + 1.0e-3_dp*f(1)/max(1.0_dp, abs(f(1)))   ! keep the loop honest
        end do
        call system_clock(t1)
        seconds = real(t1 - t0, dp)/real(rate, dp)
        best = min(best, seconds)
    end do
    print '(es12.5)', best/real(nrep, dp)/real(mesh%nel, dp)
end program bench_fe_tangent
