!> Observations: the one table of what an experiment can measure (issue 25).
!!
!! Every observation kind has one row in KINDS: its name, unit, the
!! experiment families that can produce it (bits FAM_*), the locus it takes
!! (LOCUS_NONE: a fixed point of the arm, such as the tip; LOCUS_STATION: a
!! beam and an arc length from that beam's root; LOCUS_MODE: a mode number,
!! reserved for modal experiments), what the experiment must have for it
!! (NEED_WIRE, NEED_MOTOR), the default sigma of its probe rows, its place
!! in each family's probe list and whether its rate is computed (the column
!! of a clock offset: not for the kinds holding the accelerations). An
!! observation (observation_t) is a kind and its locus; names are parsed
!! here and only here (parse_observation):
!! `x_tip`, or `kind@beam:s` for a station (`strain@1:0.05`).
!!
!! The kind codes are the positions in KINDS; the first nine are the
!! quantity codes of the measurement tables since issue 13, so a code
!! written by an older front means what it meant. The families compute
!! their observations in their own `observe` routines
!! (beamid_static_experiments, beamid_dynamic_experiments) and check a row
!! against the experiment with observation_why_not. The Python front
!! reads the table through api_observation_table (beamid_api_deck) and keeps
!! no copy.
module beamid_observations
    use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
    use beamid_kinds, only: dp
    use beamid_status, only: fmt_int, fmt_real
    implicit none
    private

    public :: obs_kind_t, observation_t, KINDS, NKIND
    public :: kind_code, kind_label, obs_label, parse_observation, observation_why_not
    public :: kinds_list, probe_kinds, kind_table_text, same_observation, default_observations
    public :: obs_groups, fmt_short, why_detail

    !> Loci.
    integer, parameter, public :: LOCUS_NONE = 0, LOCUS_STATION = 1, LOCUS_MODE = 2
    !> A station and a mode: a mode shape entry (`shape_n@1:0.4[2]`).
    integer, parameter, public :: LOCUS_STATION_MODE = 3
    !> Family bits: static load cases, releases (the dynamics), modal tests.
    integer, parameter, public :: FAM_STATIC = 1, FAM_RELEASE = 2, FAM_MODAL = 4
    !> A modal observation crosses the binding's (kind, beam, s) arrays as
    !! kind + MODE_STRIDE * mode (make_obs decodes it; beamid.observations
    !! encodes it): the kind codes stay below MODE_STRIDE.
    integer, parameter, public :: MODE_STRIDE = 1000
    !> What an experiment must have for a kind.
    integer, parameter, public :: NEED_NONE = 0, NEED_WIRE = 1, NEED_MOTOR = 2
    !> Reasons of observation_why_not.
    integer, parameter, public :: WHY_OK = 0, WHY_KIND = 1, WHY_FAMILY = 2, WHY_WIRE = 3, &
                                  WHY_MOTOR = 4, WHY_BEAM = 5, WHY_STATION = 6

    !> Kind codes (positions in KINDS).
    integer, parameter, public :: K_X_TIP = 1, K_Y_TIP = 2, K_TIP_ANGLE = 3, K_WIRE_FORCE = 4, &
                                  K_X_ELBOW = 5, K_Y_ELBOW = 6, K_U_TIP = 7, K_W_TIP = 8, &
                                  K_MOTOR_TORQUE = 9
    !> Station kinds (LOCUS_STATION: beam b, arc length s from its root).
    integer, parameter, public :: K_X = 10, K_Y = 11, K_PSI = 12, K_CURVATURE = 13, &
                                  K_MOMENT = 14, K_STRAIN = 15, K_VEL_T = 16, K_VEL_N = 17, &
                                  K_ACCEL_T = 18, K_ACCEL_N = 19
    !> Encoders: the relative rotation at the elbow and at the root.
    integer, parameter, public :: K_ELBOW_ROTATION = 20, K_ROOT_ROTATION = 21
    !> The clamp's load cell: the force (global x and y) and the moment
    !! (counter-clockwise) that the clamp exerts on the arm.
    integer, parameter, public :: K_REACTION_X = 22, K_REACTION_Y = 23, K_REACTION_MOMENT = 24
    !> The torque of the shoulder hub (the clamp) on the arm, -M at s = 0 of
    !! beam 1: what drives a prescribed hub rotation (issue 28)
    integer, parameter, public :: K_HUB_TORQUE = 25
    !> Modal kinds (issue 27): the natural frequency and damping ratio of a
    !! mode (LOCUS_MODE) and its shape at a station (LOCUS_STATION_MODE),
    !! unit-normalized over the experiment's shape rows of that mode.
    integer, parameter, public :: K_FREQ = 26, K_DAMPING = 27, K_SHAPE_N = 28, &
                                  K_SHAPE_T = 29, K_SHAPE_PSI = 30, K_SHAPE_STRAIN = 31

    !> One row of the table.
    type :: obs_kind_t
        character(len=16) :: name = ''
        character(len=8) :: unit = ''
        integer :: families = 0        !< FAM_* bits
        integer :: locus = LOCUS_NONE
        integer :: needs = NEED_NONE
        real(dp) :: sigma = 1.0e-3_dp  !< default sigma of a probe row
        !> position in the static and in the release probe lists (0: none)
        integer :: probe_static = 0, probe_release = 0
        !> the kind that measures the same thing in other coordinates (its
        !! data sigmas count for this kind's probe sigma too; 0: none)
        integer :: twin = 0
        character(len=72) :: about = ''
        !> the family computes the kind's rate (d value/dt, the column of a
        !! clock offset t0); .false. for the kinds that hold the
        !! accelerations, whose rate would need the jerk (rate=.false. in
        !! their rows below)
        logical :: rate = .true.
    end type obs_kind_t

    integer, parameter :: NKIND = 31
    integer, parameter :: BOTH = FAM_STATIC + FAM_RELEASE
    type(obs_kind_t), parameter :: KINDS(NKIND) = [ &
        obs_kind_t('x_tip', 'm', BOTH, LOCUS_NONE, NEED_NONE, 1.0e-3_dp, 1, 0, K_U_TIP, &
                   'x of the tip (the end of the last beam)'), &
        obs_kind_t('y_tip', 'm', BOTH, LOCUS_NONE, NEED_NONE, 1.0e-3_dp, 2, 0, K_W_TIP, &
                   'y of the tip'), &
        obs_kind_t('tip_angle', 'rad', BOTH, LOCUS_NONE, NEED_NONE, 1.0e-3_dp, 3, 3, 0, &
                   'tangent angle of the tip, counter-clockwise from +x'), &
        obs_kind_t('wire_force', 'N', FAM_STATIC, LOCUS_NONE, NEED_WIRE, 0.1_dp, 4, 0, 0, &
                   'tension of the radial wire'), &
        obs_kind_t('x_elbow', 'm', BOTH, LOCUS_NONE, NEED_NONE, 1.0e-3_dp, 5, 4, 0, &
                   'x of the elbow (the end of beam 1)'), &
        obs_kind_t('y_elbow', 'm', BOTH, LOCUS_NONE, NEED_NONE, 1.0e-3_dp, 6, 5, 0, &
                   'y of the elbow'), &
        obs_kind_t('u_tip', 'm', BOTH, LOCUS_NONE, NEED_NONE, 1.0e-3_dp, 0, 1, K_X_TIP, &
                   'x_tip minus the arm length (L1 + ... + Ln)'), &
        obs_kind_t('w_tip', 'm', BOTH, LOCUS_NONE, NEED_NONE, 1.0e-3_dp, 0, 2, K_Y_TIP, &
                   'y_tip (the transverse tip deflection)'), &
        obs_kind_t('motor_torque', 'N m', FAM_RELEASE, LOCUS_NONE, NEED_MOTOR, 1.0e-2_dp, 0, &
                   6, 0, 'torque of the tip motor (Eq. 159)'), &
        obs_kind_t('x', 'm', BOTH, LOCUS_STATION, NEED_NONE, 1.0e-3_dp, 0, 0, 0, &
                   'x of the station (a camera marker)'), &
        obs_kind_t('y', 'm', BOTH, LOCUS_STATION, NEED_NONE, 1.0e-3_dp, 0, 0, 0, &
                   'y of the station'), &
        obs_kind_t('psi', 'rad', BOTH, LOCUS_STATION, NEED_NONE, 1.0e-3_dp, 0, 0, 0, &
                   'tangent angle, counter-clockwise from +x'), &
        obs_kind_t('curvature', '1/m', BOTH, LOCUS_STATION, NEED_NONE, 1.0e-2_dp, 0, &
                   0, 0, 'curvature dpsi/ds, positive counter-clockwise'), &
        obs_kind_t('moment', 'N m', BOTH, LOCUS_STATION, NEED_NONE, 1.0e-2_dp, 0, 0, 0, &
                   'bending moment EI chi + C chi^3'), &
        obs_kind_t('strain', '1', BOTH, LOCUS_STATION, NEED_NONE, 1.0e-6_dp, 0, 0, 0, &
                   'gauge surface strain on the clockwise side: e + kappa t/2'), &
        obs_kind_t('vel_t', 'm/s', FAM_RELEASE, LOCUS_STATION, NEED_NONE, 1.0e-3_dp, 0, 0, 0, &
                   'velocity along the local tangent'), &
        obs_kind_t('vel_n', 'm/s', FAM_RELEASE, LOCUS_STATION, NEED_NONE, 1.0e-3_dp, 0, 0, 0, &
                   'velocity along the local normal (tangent turned +90 degrees)'), &
        obs_kind_t('accel_t', 'm/s^2', FAM_RELEASE, LOCUS_STATION, NEED_NONE, 1.0e-2_dp, 0, 0, &
                   0, 'acceleration along the local tangent (an accelerometer)', &
                   rate=.false.), &
        obs_kind_t('accel_n', 'm/s^2', FAM_RELEASE, LOCUS_STATION, NEED_NONE, 1.0e-2_dp, 0, 0, &
                   0, 'acceleration along the local normal', rate=.false.), &
        obs_kind_t('elbow_rotation', 'rad', BOTH, LOCUS_NONE, NEED_NONE, 1.0e-3_dp, 0, 0, 0, &
                   'encoder at the elbow: psi after it minus psi before it'), &
        obs_kind_t('root_rotation', 'rad', BOTH, LOCUS_NONE, NEED_NONE, 1.0e-3_dp, 0, 0, 0, &
                   'encoder at the root: psi of the arm at the clamp'), &
        obs_kind_t('reaction_x', 'N', BOTH, LOCUS_NONE, NEED_NONE, 1.0e-2_dp, 0, 0, 0, &
                   'load cell: x force of the clamp on the arm (global axes)', &
                   rate=.false.), &
        obs_kind_t('reaction_y', 'N', BOTH, LOCUS_NONE, NEED_NONE, 1.0e-2_dp, 0, 0, 0, &
                   'load cell: y force of the clamp on the arm (global axes)', &
                   rate=.false.), &
        obs_kind_t('reaction_moment', 'N m', BOTH, LOCUS_NONE, NEED_NONE, 1.0e-2_dp, 0, 0, &
                   0, 'load cell: moment of the clamp on the arm, counter-clockwise', &
                   rate=.false.), &
        obs_kind_t('hub_torque', 'N m', FAM_RELEASE, LOCUS_NONE, NEED_NONE, 1.0e-2_dp, 0, 0, &
                   0, 'torque of the hub (clamp) on the arm: -moment at the root'), &
        obs_kind_t('freq', 'Hz', FAM_MODAL, LOCUS_MODE, NEED_NONE, 1.0e-2_dp, 0, 0, 0, &
                   'natural frequency of the mode'), &
        obs_kind_t('damping', '1', FAM_MODAL, LOCUS_MODE, NEED_NONE, 1.0e-3_dp, 0, 0, 0, &
                   'damping ratio of the mode (damped models)'), &
        obs_kind_t('shape_n', '1', FAM_MODAL, LOCUS_STATION_MODE, NEED_NONE, 1.0e-2_dp, 0, 0, &
                   0, 'mode shape: displacement along the local normal'), &
        obs_kind_t('shape_t', '1', FAM_MODAL, LOCUS_STATION_MODE, NEED_NONE, 1.0e-2_dp, 0, 0, &
                   0, 'mode shape: displacement along the local tangent'), &
        obs_kind_t('shape_psi', '1', FAM_MODAL, LOCUS_STATION_MODE, NEED_NONE, 1.0e-2_dp, 0, &
                   0, 0, 'mode shape: rotation (change of psi)'), &
        obs_kind_t('shape_strain', '1', FAM_MODAL, LOCUS_STATION_MODE, NEED_NONE, 1.0e-2_dp, &
                   0, 0, 0, 'mode shape: change of the gauge strain')]

    !> An observation: a kind and its locus.
    type :: observation_t
        integer :: kind = 0
        integer :: beam = 0       !< LOCUS_STATION: the beam (1-based)
        real(dp) :: s = 0.0_dp    !< LOCUS_STATION: arc length from the beam's root (m)
        integer :: mode = 0       !< LOCUS_MODE: the mode number
    end type observation_t

contains

    !> Code of a kind name (0 when unknown).
    pure integer function kind_code(name)
        character(len=*), intent(in) :: name
        integer :: i
        kind_code = 0
        do i = 1, NKIND
            if (trim(adjustl(name)) == trim(KINDS(i)%name)) kind_code = i
        end do
    end function kind_code

    !> Name of kind k ('?' outside the table).
    pure function kind_label(k) result(name)
        integer, intent(in) :: k
        character(len=:), allocatable :: name
        if (k >= 1 .and. k <= NKIND) then
            name = trim(KINDS(k)%name)
        else
            name = '?'
        end if
    end function kind_label

    !> The name of an observation as parse_observation reads it.
    pure function obs_label(o) result(name)
        type(observation_t), intent(in) :: o
        character(len=:), allocatable :: name
        name = kind_label(o%kind)
        if (o%kind < 1 .or. o%kind > NKIND) return
        select case (KINDS(o%kind)%locus)
        case (LOCUS_STATION)
            name = name//'@'//fmt_int(o%beam)//':'//fmt_short(o%s)
        case (LOCUS_MODE)
            name = name//'['//fmt_int(o%mode)//']'
        case (LOCUS_STATION_MODE)
            name = name//'@'//fmt_int(o%beam)//':'//fmt_short(o%s)//'['//fmt_int(o%mode)//']'
        end select
    end function obs_label

    !> The shortest decimal text of x that reads back as x (fixed point
    !! up to 17 decimals, else fmt_real).
    pure function fmt_short(x) result(text)
        real(dp), intent(in) :: x
        character(len=:), allocatable :: text
        character(len=64) :: buf
        character(len=16) :: form
        real(dp) :: back
        integer :: d, ios
        text = fmt_real(x)
        if (.not. ieee_is_finite(x)) return
        if (abs(x) >= 1.0e15_dp) return
        do d = 0, 17
            write (form, '(a, i0, a)') '(f0.', d, ')'
            write (buf, form) x
            read (buf, *, iostat=ios) back
            if (ios == 0 .and. back == x) then
                text = trim(adjustl(buf))
                if (text(1:1) == '.') text = '0'//text
                if (len(text) >= 2) then
                    if (text(1:2) == '-.') text = '-0'//text(2:)
                end if
                if (text(len(text):) == '.') text = text(:len(text) - 1)
                return
            end if
        end do
    end function fmt_short

    !> Group numbers of a list of observations: equal observations get the
    !! same number, numbered in first-use order.
    pure function obs_groups(obs) result(g)
        type(observation_t), intent(in) :: obs(:)
        integer :: g(size(obs))
        integer :: i, j
        do i = 1, size(obs)
            g(i) = i
            do j = 1, i - 1
                if (same_observation(obs(j), obs(i))) then
                    g(i) = g(j)
                    exit
                end if
            end do
        end do
    end function obs_groups

    !> Two observations are the same (kind and locus).
    elemental logical function same_observation(a, b)
        type(observation_t), intent(in) :: a, b
        same_observation = a%kind == b%kind .and. a%beam == b%beam .and. a%s == b%s .and. &
                           a%mode == b%mode
    end function same_observation

    !> The observation list of the kind codes themselves (observation k is
    !! kind k, no locus): what a row's code means when a caller gives no list.
    pure function default_observations() result(obs)
        type(observation_t) :: obs(NKIND)
        integer :: k
        obs = [(observation_t(kind=k), k=1, NKIND)]
    end function default_observations

    !> Parse an observation name: a kind (`x_tip`), `kind@beam:s` for a
    !! station (beam >= 1, s >= 0 in metres from the beam's root) or
    !! `kind@mode` for a modal one. why = '' on success, else what is wrong
    !! (the caller names the file, line and field).
    pure subroutine parse_observation(text, o, why)
        character(len=*), intent(in) :: text
        type(observation_t), intent(out) :: o
        character(len=:), allocatable, intent(out) :: why
        character(len=:), allocatable :: t, kname, locus
        integer :: at, colon, ios, bra, mode
        why = ''
        t = trim(adjustl(text))
        ! a mode number in brackets at the end: freq[2], shape_n@1:0.4[2]
        mode = 0
        bra = index(t, '[')
        if (bra > 0) then
            if (t(len(t):) /= ']' .or. bra == len(t) - 1) then
                why = 'mode of "'//t//'", expected a mode number in brackets: kind[mode]'
                return
            end if
            read (t(bra + 1:len(t) - 1), *, iostat=ios) mode
            if (ios /= 0 .or. verify(trim(adjustl(t(bra + 1:len(t) - 1))), '0123456789') /= 0 &
                .or. mode < 1) then
                why = 'mode "'//t(bra + 1:len(t) - 1)//'" of "'//t//'", expected a mode '// &
                      'number >= 1'
                return
            end if
            t = t(:bra - 1)
        end if
        at = index(t, '@')
        if (at == 0) then
            kname = t
            locus = ''
        else
            kname = t(:at - 1)
            locus = t(at + 1:)
        end if
        o%kind = kind_code(kname)
        if (o%kind == 0 .or. len(kname) == 0) then
            why = 'unknown observation kind "'//kname//'", expected one of '//kinds_list()
            o%kind = 0
            return
        end if
        if (KINDS(o%kind)%locus == LOCUS_MODE .or. KINDS(o%kind)%locus == LOCUS_STATION_MODE) then
            if (mode == 0) then
                if (KINDS(o%kind)%locus == LOCUS_STATION_MODE) then
                    why = '"'//kname//'" needs a station and a mode number: '//kname// &
                          '@beam:s[mode]'
                else
                    why = '"'//kname//'" needs a mode number: '//kname//'[mode]'
                end if
                return
            end if
            o%mode = mode
        else if (bra > 0) then
            why = '"'//kname//'" takes no mode number, got "'//trim(adjustl(text))//'"'
            return
        end if
        select case (KINDS(o%kind)%locus)
        case (LOCUS_NONE)
            if (at > 0) why = '"'//kname//'" is a fixed point of the arm and takes no '// &
                              'locus, got "'//t//'"'
        case (LOCUS_STATION, LOCUS_STATION_MODE)
            if (at == 0) then
                why = '"'//kname//'" needs a station: '//kname//'@beam:s (beam number, '// &
                      'arc length s in m from the beam''s root)'
                return
            end if
            colon = index(locus, ':')
            if (colon == 0) then
                why = 'station "'//locus//'" of "'//t//'", expected beam:s'
                return
            end if
            read (locus(:colon - 1), *, iostat=ios) o%beam
            if (ios /= 0 .or. verify(trim(adjustl(locus(:colon - 1))), '0123456789') /= 0 &
                .or. len_trim(locus(:colon - 1)) == 0) then
                why = 'beam "'//locus(:colon - 1)//'" of "'//t//'", expected a beam number'
                return
            end if
            read (locus(colon + 1:), *, iostat=ios) o%s
            if (ios /= 0 .or. len_trim(locus(colon + 1:)) == 0) then
                why = 'arc length "'//locus(colon + 1:)//'" of "'//t//'", expected a number (m)'
                return
            end if
            if (.not. ieee_is_finite(o%s)) then
                why = 'arc length s = '//fmt_real(o%s)//' of "'//t//'", expected 0 <= s <= L'
            else if (o%beam < 1) then
                why = 'beam '//fmt_int(o%beam)//' of "'//t//'", expected a beam >= 1'
            else if (o%s < 0.0_dp) then
                why = 'arc length s = '//fmt_short(o%s)//' of "'//t//'", expected 0 <= s <= L'
            end if
        case (LOCUS_MODE)
            if (at > 0) why = '"'//kname//'" takes a mode number only: '//kname//'[mode]'
        end select
    end subroutine parse_observation

    !> Whether observation o can be measured in an experiment of family
    !! `family` (FAM_*): WHY_OK, or the reason it cannot (WHY_FAMILY: a kind
    !! the family does not produce, WHY_WIRE, WHY_MOTOR: a wire or motor the
    !! experiment lacks, WHY_BEAM: a beam beyond nbeams, WHY_STATION: a
    !! station beyond its beam's length lengths(b), not checked when lengths
    !! is empty, WHY_KIND: no such kind). why_detail says what was expected;
    !! each caller phrases the rest in its own terms (file and line, row,
    !! experiment).
    pure integer function observation_why_not(o, family, has_wire, has_motor, nbeams, &
                                              lengths) result(why)
        type(observation_t), intent(in) :: o
        integer, intent(in) :: family, nbeams
        logical, intent(in) :: has_wire, has_motor
        real(dp), intent(in) :: lengths(:)
        type(obs_kind_t) :: k
        why = WHY_OK
        if (o%kind < 1 .or. o%kind > NKIND) then
            why = WHY_KIND
            return
        end if
        k = KINDS(o%kind)
        if (iand(k%families, family) == 0) then
            why = WHY_FAMILY
        else if (k%needs == NEED_WIRE .and. .not. has_wire) then
            why = WHY_WIRE
        else if (k%needs == NEED_MOTOR .and. .not. has_motor) then
            why = WHY_MOTOR
        else if (o%kind == K_ELBOW_ROTATION .and. nbeams < 2) then
            why = WHY_BEAM
        else if (k%locus == LOCUS_STATION .or. k%locus == LOCUS_STATION_MODE) then
            if (o%beam < 1 .or. o%beam > nbeams) then
                why = WHY_BEAM
            else if (size(lengths) >= o%beam) then
                if (o%s < 0.0_dp .or. o%s > lengths(o%beam)*(1.0_dp + 1.0e-12_dp)) &
                    why = WHY_STATION
            end if
        end if
    end function observation_why_not

    !> What was expected, for a reason of observation_why_not (WHY_KIND,
    !! WHY_FAMILY, WHY_BEAM, WHY_STATION; '' for the others).
    pure function why_detail(o, reason, family, nbeams, lengths) result(detail)
        type(observation_t), intent(in) :: o
        integer, intent(in) :: reason, family, nbeams
        real(dp), intent(in) :: lengths(:)
        character(len=:), allocatable :: detail
        detail = ''
        select case (reason)
        case (WHY_KIND)
            detail = 'observation kind code '//fmt_int(o%kind)//', expected 1..'//fmt_int(NKIND)
        case (WHY_FAMILY)
            if (KINDS(o%kind)%families == FAM_MODAL) then
                detail = 'only a modal experiment measures '//kind_label(o%kind)
            else if (family == FAM_MODAL) then
                detail = 'a modal experiment measures freq, damping and shape_* only'
            else if (family == FAM_STATIC) then
                detail = 'only a release experiment measures '//kind_label(o%kind)
            else
                detail = 'only a static experiment measures '//kind_label(o%kind)
            end if
        case (WHY_BEAM)
            if (o%kind == K_ELBOW_ROTATION) then
                detail = 'a chain of '//fmt_int(nbeams)//' beam has no elbow'
            else
                detail = 'beam '//fmt_int(o%beam)//' does not exist, expected 1..'// &
                         fmt_int(nbeams)
            end if
        case (WHY_STATION)
            if (size(lengths) >= o%beam .and. o%beam >= 1) then
                detail = 'station s = '//fmt_short(o%s)//' is beyond beam '//fmt_int(o%beam)// &
                         ', expected 0 <= s <= '//fmt_short(lengths(o%beam))
            end if
        end select
    end function why_detail

    !> The kind names, comma separated (for messages).
    pure function kinds_list() result(text)
        character(len=:), allocatable :: text
        integer :: k
        text = kind_label(1)
        do k = 2, NKIND
            text = text//', '//kind_label(k)
            if (KINDS(k)%locus == LOCUS_STATION) text = text//'@beam:s'
            if (KINDS(k)%locus == LOCUS_MODE) text = text//'[mode]'
            if (KINDS(k)%locus == LOCUS_STATION_MODE) text = text//'@beam:s[mode]'
        end do
    end function kinds_list

    !> The probe kinds of a family (FAM_STATIC or FAM_RELEASE), in probe order.
    pure function probe_kinds(family) result(ks)
        integer, intent(in) :: family
        integer, allocatable :: ks(:)
        integer :: k, pos(NKIND), n
        pos = 0
        do k = 1, NKIND
            if (family == FAM_STATIC) pos(k) = KINDS(k)%probe_static
            if (family == FAM_RELEASE) pos(k) = KINDS(k)%probe_release
        end do
        n = count(pos > 0)
        allocate (ks(n))
        do k = 1, NKIND
            if (pos(k) > 0) ks(pos(k)) = k
        end do
    end function probe_kinds

    !> The table as text, one kind per line:
    !! name;unit;families;locus;needs;sigma;probe_static;probe_release;twin;rate;about
    !! (families: static, release, modal joined by '+'; locus: none, station,
    !! mode, station+mode;
    !! needs: none, wire, motor; probe_*: the place in that family's probe
    !! list, 0: none; twin: the kind's twin by name, '' for none; rate:
    !! 'rate' or 'no_rate', whether the rate d value/dt is computed).
    pure function kind_table_text() result(text)
        character(len=:), allocatable :: text
        character(len=*), parameter :: LOCI(0:3) = [character(len=12) :: 'none', 'station', &
                                                     'mode', 'station+mode']
        character(len=*), parameter :: NEEDS(0:2) = [character(len=5) :: 'none', 'wire', &
                                                     'motor']
        character(len=:), allocatable :: fam, twin
        character(len=32) :: buf
        type(obs_kind_t) :: r
        integer :: k
        text = ''
        do k = 1, NKIND
                r = KINDS(k)
                fam = ''
                if (iand(r%families, FAM_STATIC) /= 0) fam = 'static'
                if (iand(r%families, FAM_RELEASE) /= 0) then
                    if (len(fam) > 0) fam = fam//'+'
                    fam = fam//'release'
                end if
                if (iand(r%families, FAM_MODAL) /= 0) then
                    if (len(fam) > 0) fam = fam//'+'
                    fam = fam//'modal'
                end if
                write (buf, '(es24.16)') r%sigma
                twin = ''
                if (r%twin > 0) twin = trim(KINDS(r%twin)%name)
                text = text//trim(r%name)//';'//trim(r%unit)//';'//fam//';'// &
                       trim(LOCI(r%locus))//';'//trim(NEEDS(r%needs))//';'// &
                       trim(adjustl(buf))//';'//fmt_int(r%probe_static)//';'// &
                       fmt_int(r%probe_release)//';'//twin//';'// &
                       trim(merge('rate   ', 'no_rate', r%rate))//';'//trim(r%about)// &
                       new_line('a')
        end do
    end function kind_table_text
end module beamid_observations
