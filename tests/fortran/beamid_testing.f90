!> Checks for the Fortran test programs of tests/fortran (run by `meson test`).
!!
!! A test program keeps a checks_t, calls check_* for each assertion (a
!! failure prints the name, the values and the tolerance) and ends with
!! check_finish, which stops with exit code 1 when any check failed. Test
!! programs may print and stop; library code never does.
module beamid_testing
    use, intrinsic :: iso_fortran_env, only: output_unit, error_unit
    use beamid_kinds, only: dp
    implicit none
    private

    public :: checks_t, check_close, check_below, check_true, check_finish, seed_random

    !> Running tally of a test program.
    type :: checks_t
        integer :: passed = 0
        integer :: failed = 0
    end type checks_t

    !> |got - want| <= atol + rtol |want|, elementwise.
    interface check_close
        module procedure check_close_scalar, check_close_vector, check_close_matrix
    end interface check_close

contains

    subroutine check_true(t, name, ok)
        type(checks_t), intent(inout) :: t
        character(len=*), intent(in) :: name
        logical, intent(in) :: ok
        if (ok) then
            t%passed = t%passed + 1
        else
            t%failed = t%failed + 1
            write (error_unit, '(a)') 'FAIL '//name
        end if
    end subroutine check_true

    !> value <= bound (a NaN fails).
    subroutine check_below(t, name, value, bound)
        type(checks_t), intent(inout) :: t
        character(len=*), intent(in) :: name
        real(dp), intent(in) :: value, bound
        if (value <= bound) then
            t%passed = t%passed + 1
        else
            t%failed = t%failed + 1
            write (error_unit, '(a, es12.4, a, es12.4)') 'FAIL '//name//': ', value, &
                ' above ', bound
        end if
    end subroutine check_below

    subroutine check_close_scalar(t, name, got, want, rtol, atol)
        type(checks_t), intent(inout) :: t
        character(len=*), intent(in) :: name
        real(dp), intent(in) :: got, want, rtol, atol
        call check_close_vector(t, name, [got], [want], rtol, atol)
    end subroutine check_close_scalar

    subroutine check_close_matrix(t, name, got, want, rtol, atol)
        type(checks_t), intent(inout) :: t
        character(len=*), intent(in) :: name
        real(dp), intent(in) :: got(:, :), want(:, :), rtol, atol
        call check_close_vector(t, name, reshape(got, [size(got)]), reshape(want, [size(want)]), &
                                rtol, atol)
    end subroutine check_close_matrix

    subroutine check_close_vector(t, name, got, want, rtol, atol)
        type(checks_t), intent(inout) :: t
        character(len=*), intent(in) :: name
        real(dp), intent(in) :: got(:), want(:), rtol, atol
        integer :: i
        if (size(got) /= size(want)) then
            t%failed = t%failed + 1
            write (error_unit, '(a, 2i8)') 'FAIL '//name//': sizes differ', size(got), size(want)
            return
        end if
        do i = 1, size(got)
            ! written so that a NaN fails
            if (.not. (abs(got(i) - want(i)) <= atol + rtol*abs(want(i)))) then
                t%failed = t%failed + 1
                write (error_unit, '(a, i0, a, es24.16, a, es24.16, a, es10.3, a, es10.3)') &
                    'FAIL '//name//' (', i, '): got ', got(i), ' want ', want(i), &
                    ' rtol ', rtol, ' atol ', atol
                return
            end if
        end do
        t%passed = t%passed + 1
    end subroutine check_close_vector

    !> Print the tally; exit code 1 when a check failed.
    subroutine check_finish(t, program_name)
        type(checks_t), intent(in) :: t
        character(len=*), intent(in) :: program_name
        write (output_unit, '(a, i0, a, i0, a)') program_name//': ', t%passed, ' checks passed, ', &
            t%failed, ' failed'
        if (t%failed > 0) error stop 1
    end subroutine check_finish

    !> A fixed seed for random_number, so that every run draws the same numbers.
    subroutine seed_random(seed)
        integer, intent(in) :: seed
        integer :: n, i
        integer, allocatable :: s(:)
        call random_seed(size=n)
        allocate (s(n))
        s = [(seed + 7919*i, i = 1, n)]
        call random_seed(put=s)
    end subroutine seed_random
end module beamid_testing
