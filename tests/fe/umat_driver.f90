! A Fortran driver of libsubslip_fe's UMAT, called as Abaqus calls a user material: uniaxial
! stress along 33 (a Newton iteration on the five lateral strain increments with DDSDDE), then
! simple shear out and back, for the FCC crystal of the FE tests (tests/fe/umat_call.hpp); then
! uniaxial stress at finite strain (PROPS(2) = 1, as under NLGEOM): each increment DFGRD1 =
! exp(E) DFGRD0 with E symmetric, the Newton iteration with DDSDDE on E's lateral components.
! Each increment prints one line: the path (U, S or F), the increment, STRESS(1:6) and
! STATEV(1:89).
program umat_driver
  implicit none
  integer, parameter :: dp = kind(1.0d0)
  integer, parameter :: ntens = 6, nstatv = 89, nprops = 26
  real(dp) :: stress(ntens), statev(nstatv), ddsdde(ntens, ntens)
  real(dp) :: props(nprops), dstran(ntens)
  real(dp) :: stress0(ntens), statev0(nstatv)
  real(dp) :: jac(5, 5), res(5), step(5)
  real(dp) :: fgrad0(3, 3), fgrad1(3, 3), identity(3, 3)
  integer :: lateral(5) = (/ 1, 2, 4, 5, 6 /)
  integer :: k, it, a, b
  real(dp) :: pnewdt
  ! The largest stress of the path so far: the lateral stresses are resolved relative to it (the
  ! axial stress passes near zero after a reversal, the round-off of the grain's solve does not).
  real(dp) :: path_scale
  logical :: converged

  props = 0.0_dp
  props(1) = 1;  props(2) = 0;  props(3) = 1
  props(4) = 168400.0_dp;  props(5) = 121400.0_dp;  props(6) = 75400.0_dp
  props(7) = 10.0_dp
  props(8) = 1.0_dp;  props(9) = 3.0_dp;  props(10) = 5.0_dp;  props(11) = 0.0_dp
  props(12) = 1;  props(13) = 200.0_dp
  props(14) = 1;  props(15) = 1.0e-3_dp;  props(16) = 16.0_dp;  props(17) = 1.6_dp
  props(24) = 30.0_dp;  props(25) = 40.0_dp;  props(26) = 50.0_dp
  identity = 0.0_dp;  identity(1, 1) = 1;  identity(2, 2) = 1;  identity(3, 3) = 1
  fgrad0 = identity;  fgrad1 = identity

  ! Uniaxial stress: tension, then back into compression.
  stress = 0.0_dp;  statev = 0.0_dp;  path_scale = 0.0_dp
  do k = 1, 50
    dstran = 0.0_dp
    dstran(3) = 2.0e-4_dp
    if (k > 20) dstran(3) = -2.0e-4_dp
    stress0 = stress;  statev0 = statev
    converged = .false.
    do it = 1, 30
      stress = stress0;  statev = statev0
      call increment(dstran, 0.2_dp, pnewdt)
      if (pnewdt < 1.0_dp) stop 2
      do a = 1, 5
        res(a) = stress(lateral(a))
        do b = 1, 5
          jac(a, b) = ddsdde(lateral(a), lateral(b))
        end do
      end do
      if (sqrt(sum(res**2)) <= 1.0e-11_dp * max(path_scale, abs(stress(3)))) then
        converged = .true.
        exit
      end if
      call solve(jac, res, step)
      do a = 1, 5
        dstran(lateral(a)) = dstran(lateral(a)) - step(a)
      end do
    end do
    if (.not. converged) stop 3
    path_scale = max(path_scale, maxval(abs(stress)))
    write (*, '(A,1X,I4,95(1X,ES25.17E3))') 'U', k, stress, statev
  end do

  ! Simple shear, out and back.
  stress = 0.0_dp;  statev = 0.0_dp
  do k = 1, 90
    dstran = 0.0_dp
    dstran(4) = 2.0e-4_dp
    if (k > 30) dstran(4) = -2.0e-4_dp
    call increment(dstran, 0.1_dp, pnewdt)
    if (pnewdt < 1.0_dp) stop 4
    write (*, '(A,1X,I4,95(1X,ES25.17E3))') 'S', k, stress, statev
  end do

  ! Uniaxial stress at finite strain: the same path as stretches exp(E) of the deformation.
  props(2) = 1
  stress = 0.0_dp;  statev = 0.0_dp;  path_scale = 0.0_dp
  fgrad0 = identity
  do k = 1, 50
    dstran = 0.0_dp
    dstran(3) = 2.0e-4_dp
    if (k > 20) dstran(3) = -2.0e-4_dp
    stress0 = stress;  statev0 = statev
    converged = .false.
    do it = 1, 30
      stress = stress0;  statev = statev0
      fgrad1 = matmul(symmetric_exp(dstran), fgrad0)
      call increment(0.0_dp * dstran, 0.2_dp, pnewdt)
      if (pnewdt < 1.0_dp) stop 5
      do a = 1, 5
        res(a) = stress(lateral(a))
        do b = 1, 5
          jac(a, b) = ddsdde(lateral(a), lateral(b))
        end do
      end do
      if (sqrt(sum(res**2)) <= 1.0e-11_dp * max(path_scale, abs(stress(3)))) then
        converged = .true.
        exit
      end if
      call solve(jac, res, step)
      do a = 1, 5
        dstran(lateral(a)) = dstran(lateral(a)) - step(a)
      end do
    end do
    if (.not. converged) stop 6
    path_scale = max(path_scale, maxval(abs(stress)))
    fgrad0 = fgrad1
    write (*, '(A,1X,I4,95(1X,ES25.17E3))') 'F', k, stress, statev
  end do

contains

  ! exp(E) of the symmetric tensor E given in Abaqus' order with engineering shears, by its
  ! series (|E| ~ 1e-4: twelve terms are exact to rounding).
  function symmetric_exp(v) result(x)
    real(dp), intent(in) :: v(ntens)
    real(dp) :: x(3, 3), e(3, 3), term(3, 3)
    integer :: n
    e = 0.0_dp
    e(1, 1) = v(1);  e(2, 2) = v(2);  e(3, 3) = v(3)
    e(1, 2) = 0.5_dp * v(4);  e(2, 1) = e(1, 2)
    e(1, 3) = 0.5_dp * v(5);  e(3, 1) = e(1, 3)
    e(2, 3) = 0.5_dp * v(6);  e(3, 2) = e(2, 3)
    x = identity;  term = identity
    do n = 1, 12
      term = matmul(term, e) / real(n, dp)
      x = x + term
    end do
  end function symmetric_exp

  subroutine increment(dstran, dtime, pnewdt)
    real(dp), intent(in) :: dstran(ntens), dtime
    real(dp), intent(out) :: pnewdt
    real(dp) :: sse, spd, scd, rpl, ddsddt(ntens), drplde(ntens), drpldt
    real(dp) :: stran(ntens), time(2), temp, dtemp, predef(1), dpred(1)
    real(dp) :: coords(3), drot(3, 3), celent, dfgrd0(3, 3), dfgrd1(3, 3)
    integer :: noel, npt, layer, kspt, jstep(4), kinc
    character(len=80) :: cmname
    sse = 0;  spd = 0;  scd = 0;  rpl = 0;  ddsddt = 0;  drplde = 0;  drpldt = 0
    stran = 0;  time = 0;  temp = 293;  dtemp = 0;  predef = 0;  dpred = 0;  coords = 0
    drot = 0;  drot(1, 1) = 1;  drot(2, 2) = 1;  drot(3, 3) = 1
    dfgrd0 = fgrad0;  dfgrd1 = fgrad1;  celent = 1
    noel = 1;  npt = 1;  layer = 1;  kspt = 1;  jstep = (/ 1, 0, 1, 0 /);  kinc = 1
    cmname = 'SUBSLIP'
    pnewdt = 1.0_dp
    call UMAT(stress, statev, ddsdde, sse, spd, scd, rpl, ddsddt, drplde, drpldt, stran, &
              dstran, time, dtime, temp, dtemp, predef, dpred, cmname, 3, 3, ntens, nstatv, &
              props, nprops, coords, drot, pnewdt, celent, dfgrd0, dfgrd1, noel, npt, layer, &
              kspt, jstep, kinc)
  end subroutine increment

  ! Gaussian elimination with partial pivoting: x = a^-1 r.
  subroutine solve(a_in, r_in, x)
    real(dp), intent(in) :: a_in(5, 5), r_in(5)
    real(dp), intent(out) :: x(5)
    real(dp) :: a(5, 5), r(5), f, row(5), t
    integer :: i, j, p
    a = a_in;  r = r_in
    do i = 1, 5
      p = i - 1 + maxloc(abs(a(i:5, i)), 1)
      row = a(i, :);  a(i, :) = a(p, :);  a(p, :) = row
      t = r(i);  r(i) = r(p);  r(p) = t
      do j = i + 1, 5
        f = a(j, i) / a(i, i)
        a(j, :) = a(j, :) - f * a(i, :)
        r(j) = r(j) - f * r(i)
      end do
    end do
    do i = 5, 1, -1
      x(i) = (r(i) - sum(a(i, i + 1:5) * x(i + 1:5))) / a(i, i)
    end do
  end subroutine solve

end program umat_driver
