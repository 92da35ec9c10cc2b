!> Status messages have no length limit; at the f2py boundary status_out
!! copies one into the caller's buffer and marks a cut, never clipping it
!! silently. A status that was never set gives code 0 and an empty message.
program test_status
    use beamid_status, only: status_t, set_status, status_out, clear_status, ERR_INPUT, &
                             STATUS_OK
    use beamid_testing, only: checks_t, check_true, check_finish
    implicit none
    type(checks_t) :: t
    type(status_t) :: stat
    character(len=256) :: buffer
    character(len=20) :: small
    character(len=600) :: long
    integer :: code

    call status_out(stat, code, buffer)
    call check_true(t, 'a fresh status is ok with an empty message', &
                    code == STATUS_OK .and. buffer == '')
    call set_status(stat, ERR_INPUT, 'reader', 'bad value')
    call status_out(stat, code, buffer)
    call check_true(t, 'a short message is copied whole', &
                    code == ERR_INPUT .and. buffer == 'reader: bad value')
    long = repeat('0123456789', 60)
    call set_status(stat, ERR_INPUT, 'reader', long)
    call check_true(t, 'the status keeps a 608-character message whole', &
                    len(stat%message) == 608 .and. stat%message(9:) == long)
    call status_out(stat, code, buffer)
    call check_true(t, 'a long message is cut and says so: '//trim(buffer(200:)), &
                    buffer(1:8) == 'reader: ' .and. &
                    index(buffer, '... (truncated: 608 characters)') + 30 == len(buffer))
    call status_out(stat, code, small)
    call check_true(t, 'a buffer shorter than the mark gets the start of the mark', &
                    small == '... (truncated: 608 ')
    call clear_status(stat)
    call status_out(stat, code, buffer)
    call check_true(t, 'a cleared status is ok with an empty message', &
                    code == STATUS_OK .and. buffer == '')
    call check_finish(t, 'test_status')
end program test_status
