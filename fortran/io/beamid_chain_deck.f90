!> The measurement chain of an estimation deck (issue 29; docs/decks.md,
!! "The measurement chain"): the &fit keys time_offset, bias, scale, loss,
!! burn_in, estimate_sigma and initial_velocity, read into the experiments'
!! specs as beamid.fit sets them (keys t0, bias, scale, loss, burn_in,
!! sigma_est, v0 of beamid_family's SPEC_KEYS), so a deck and the Python API
!! fit one problem.
!!
!! A channel is `experiment:quantity` (`free:w_tip`, `free:strain@1:0.05`)
!! or a bare quantity (that quantity in every experiment measuring it);
!! estimate_sigma = 'all' is every channel. The channel masks number the
!! entries of the deck's observation list in the core's order
!! (ordered_observations: by kind code, beam, arc length, mode; Python's
!! beamid.observations.ordered), so both fronts name the same parameters.
!!
!! Library code: no printing, no STOP; problems are added to `errors`, one
!! line each, as the deck reader collects them.
module beamid_chain_deck
    use beamid_kinds, only: dp
    use beamid_status, only: fmt_int
    use beamid_namelist, only: nml_text_t, add_error
    use beamid_observations, only: observation_t, obs_label, same_observation, parse_observation
    use beamid_inverse, only: EXP_RELEASE, EV_T0, EV_BIAS, EV_SCALE, EV_LOSS, EV_BURNIN, &
                              EV_SIGEST, MAX_CHANNEL_BITS, EV_V0, experiment_spec_t
    implicit none
    private

    public :: ordered_observations, chain_asked, set_chain_key, CHAIN_KEYS, chain_sigma_missing
    !> The &fit keys of the measurement chain (nml_check_keys' list form).
    character(len=*), parameter :: CHAIN_KEYS = ' time_offset bias scale loss burn_in '// &
                                                'estimate_sigma initial_velocity '
    character(len=*), parameter :: LOSS_NAMES(0:2) = [character(len=6) :: 'linear', 'huber', &
                                                      'cauchy']

contains

    !> The distinct observations of obs in the core's order (kind code,
    !! beam, arc length, mode), as beamid.observations.ordered.
    pure function ordered_observations(obs) result(list)
        type(observation_t), intent(in) :: obs(:)
        type(observation_t), allocatable :: list(:)
        type(observation_t) :: x
        integer :: i, j
        allocate (list(0))
        do i = 1, size(obs)
            if (any(same_observation(list, obs(i)))) cycle
            list = [list, obs(i)]
            ! insertion: move the new entry before every entry it precedes
            do j = size(list), 2, -1
                if (.not. before(list(j), list(j - 1))) exit
                x = list(j)
                list(j) = list(j - 1)
                list(j - 1) = x
            end do
        end do
    contains
        pure logical function before(a, b)
            type(observation_t), intent(in) :: a, b
            if (a%kind /= b%kind) then
                before = a%kind < b%kind
            else if (a%beam /= b%beam) then
                before = a%beam < b%beam
            else if (a%s /= b%s) then
                before = a%s < b%s
            else
                before = a%mode < b%mode
            end if
        end function before
    end function ordered_observations

    !> Does an experiment's spec ask anything of the chain?
    pure logical function chain_asked(specs)
        type(experiment_spec_t), intent(in) :: specs(:)
        chain_asked = any(specs%chain_asked())
    end function chain_asked

    !> One chain key of a deck's &fit (`key` one of CHAIN_KEYS, `items` its
    !! values as text) into the specs `specs` of the experiments
    !! `names` (kinds `kinds`) for the data rows (experiment `row_exp`,
    !! observation `row_obs`). `where` starts each message.
    subroutine set_chain_key(key, items, names, kinds, row_exp, row_obs, specs, where, errors)
        character(len=*), intent(in) :: key, where
        type(nml_text_t), intent(in) :: items(:)
        character(len=*), intent(in) :: names(:)
        integer, intent(in) :: kinds(:), row_exp(:)
        type(observation_t), intent(in) :: row_obs(:)
        type(experiment_spec_t), intent(inout) :: specs(:)
        character(len=:), allocatable, intent(inout) :: errors
        type(observation_t), allocatable :: list(:)
        logical, allocatable :: pick(:, :)
        integer :: i, e, q, code
        real(dp) :: t
        integer :: ios
        list = ordered_observations(row_obs)
        select case (key)
        case ('time_offset')
            do i = 1, size(items)
                e = find_name(names, items(i)%s)
                if (e == 0) then
                    call add_error(errors, where//"time_offset = '"//items(i)%s// &
                                   "': no experiment of that name (experiments: "// &
                                   joined(names)//')')
                else if (kinds(e) /= EXP_RELEASE) then
                    call add_error(errors, where//"time_offset = '"//items(i)%s// &
                                   "': the experiment is static; a time offset needs a "// &
                                   "record in time (kind = 'release')")
                else
                    call specs(e)%set(EV_T0, 1.0_dp)
                end if
            end do
        case ('initial_velocity')
            do i = 1, size(items)
                e = find_name(names, items(i)%s)
                if (e == 0) then
                    call add_error(errors, where//"initial_velocity = '"//items(i)%s// &
                                   "': no experiment of that name (experiments: "// &
                                   joined(names)//')')
                else if (kinds(e) /= EXP_RELEASE) then
                    call add_error(errors, where//"initial_velocity = '"//items(i)%s// &
                                   "': the experiment is static; an initial velocity needs "// &
                                   "a release (kind = 'release')")
                else
                    call specs(e)%set(EV_V0, 1.0_dp)
                end if
            end do
        case ('bias', 'scale', 'estimate_sigma')
            allocate (pick(size(list), size(names)), source=.false.)
            do i = 1, size(items)
                if (key == 'estimate_sigma' .and. items(i)%s == 'all') then
                    do q = 1, size(row_exp)
                        pick(findloc(same_observation(list, row_obs(q)), .true., 1), &
                             row_exp(q)) = .true.
                    end do
                    cycle
                end if
                call channels(items(i)%s, pick)
            end do
            do e = 1, size(names)
                if (.not. any(pick(:, e))) cycle
                if (size(list) > MAX_CHANNEL_BITS) then
                    call add_error(errors, where//key//': the data have '// &
                                   fmt_int(size(list))//' observations, expected at most '// &
                                   fmt_int(MAX_CHANNEL_BITS)//' for channel masks')
                    return
                end if
                t = 0.0_dp
                do q = 1, size(list)
                    if (pick(q, e)) t = t + 2.0_dp**(q - 1)
                end do
                select case (key)
                case ('bias')
                    call specs(e)%set(EV_BIAS, t)
                case ('scale')
                    call specs(e)%set(EV_SCALE, t)
                case default
                    call specs(e)%set(EV_SIGEST, t)
                end select
            end do
        case ('loss')
            if (size(items) /= 1) then
                call add_error(errors, where//'loss: expected one name ('//joined(LOSS_NAMES)//')')
                return
            end if
            code = find_name(LOSS_NAMES, items(1)%s) - 1
            if (code < 0) then
                call add_error(errors, where//"loss = '"//items(1)%s//"', expected one of "// &
                               joined(LOSS_NAMES))
                return
            end if
            call specs%set(EV_LOSS, real(code, dp))
        case ('burn_in')
            t = -1.0_dp
            ios = 1
            if (size(items) == 1) read (items(1)%s, *, iostat=ios) t
            if (ios /= 0 .or. .not. (t >= 0.0_dp .and. t < huge(t))) then
                call add_error(errors, where//'burn_in = '//shown(items)//', expected a time '// &
                               '>= 0 (s)')
            else if (.not. any(kinds == EXP_RELEASE)) then
                call add_error(errors, where//'burn_in: the experiments have no release (no '// &
                               'record in time)')
            else
                do e = 1, size(specs)
                    if (kinds(e) == EXP_RELEASE) call specs(e)%set(EV_BURNIN, t)
                end do
            end if
        case default
            call add_error(errors, where//key//': not a key of the measurement chain ('// &
                           trim(adjustl(CHAIN_KEYS))//')')
        end select
    contains
        !> The channels one item names into pick(entry, experiment).
        subroutine channels(text, pick)
            character(len=*), intent(in) :: text
            logical, intent(inout) :: pick(:, :)
            type(observation_t) :: o
            character(len=:), allocatable :: why, quantity, where_exp
            integer :: colon, ee, r, found
            colon = index(text, ':')
            ee = 0
            quantity = text
            if (colon > 1) then
                ee = find_name(names, text(:colon - 1))
                if (ee > 0) quantity = text(colon + 1:)
            end if
            call parse_observation(quantity, o, why)
            if (o%kind == 0 .or. len(why) > 0) then
                call add_error(errors, where//key//" = '"//text//"': expected a channel "// &
                               "'experiment:quantity' or a quantity"// &
                               trim(merge(' (all)', '      ', key == 'estimate_sigma'))// &
                               '; experiments: '//joined(names))
                return
            end if
            found = 0
            do r = 1, size(row_exp)
                if (.not. same_observation(row_obs(r), o)) cycle
                if (ee > 0 .and. row_exp(r) /= ee) cycle
                pick(findloc(same_observation(list, o), .true., 1), row_exp(r)) = .true.
                found = found + 1
            end do
            if (found == 0) then
                ! (the experiment named only when the channel named one)
                where_exp = ''
                if (ee > 0) where_exp = " in experiment '"//trim(names(ee))//"'"
                call add_error(errors, where//key//" = '"//text//"': no data row of "// &
                               obs_label(o)//where_exp//' (the channel does not exist)')
            end if
        end subroutine channels
    end subroutine set_chain_key

    !> The first data row without sigma (NaN) whose channel's sigma the
    !! specs do not estimate (key sigma_est); 0: none.
    pure integer function chain_sigma_missing(specs, row_exp, row_obs, sigma) result(row)
        type(experiment_spec_t), intent(in) :: specs(:)
        real(dp), intent(in) :: sigma(:)
        integer, intent(in) :: row_exp(:)
        type(observation_t), intent(in) :: row_obs(:)
        type(observation_t), allocatable :: list(:)
        integer :: r, q
        real(dp) :: mask
        list = ordered_observations(row_obs)
        do row = 1, size(sigma)
            if (sigma(row) == sigma(row)) cycle        ! given
            r = row
            q = findloc(same_observation(list, row_obs(r)), .true., 1)
            mask = specs(row_exp(r))%get(EV_SIGEST)
            if (q > MAX_CHANNEL_BITS) return
            if (.not. btest(nint(mask, kind=8), q - 1)) return
        end do
        row = 0
    end function chain_sigma_missing

    pure integer function find_name(names, name)
        character(len=*), intent(in) :: names(:), name
        integer :: i
        find_name = 0
        do i = 1, size(names)
            if (trim(names(i)) == trim(name)) then
                find_name = i
                return
            end if
        end do
    end function find_name

    pure function joined(names) result(text)
        character(len=*), intent(in) :: names(:)
        character(len=:), allocatable :: text
        integer :: i
        text = ''
        do i = 1, size(names)
            if (i > 1) text = text//', '
            text = text//trim(names(i))
        end do
    end function joined

    pure function shown(items) result(text)
        type(nml_text_t), intent(in) :: items(:)
        character(len=:), allocatable :: text
        integer :: i
        text = ''
        do i = 1, size(items)
            if (i > 1) text = text//', '
            text = text//"'"//items(i)%s//"'"
        end do
    end function shown
end module beamid_chain_deck
