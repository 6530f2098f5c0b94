!> The table of the relaxed Runge-Kutta methods and their coefficients (src/integrator/
!> butcher_tableaux): a new explicit method is a function here and one line of
!> `registered_tableaux`. A submodule, so that such an edit recompiles this file alone.
submodule (butcher_tableaux) butcher_tableaux_lines
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)

contains

  !> The relaxed integrators, a line each.
  module procedure registered_tableaux
    entries = [ &
      tableau_entry('relaxed_rk4', 'RRK4', 'classic RK4 with energy relaxation and an exact J projection, in '// &
                    'entropy variables', classic_rk4), &
      tableau_entry('relaxed_rk8', 'RRK8', 'Cooper-Verner order 8 (11 stages, weights >= 0), relaxed as relaxed_rk4', &
                    cooper_verner8), &
      tableau_entry('relaxed_dp853', 'RDP853', 'Dormand-Prince 8(5,3), relaxed, adaptive at tolerance, with the '// &
                    'entropy guard; dt is its first step', dormand_prince853), &
      tableau_entry('relaxed_gauss6', 'RGauss6', 'Gauss-Legendre with 3 stages (order 6, implicit, stages solved '// &
                    'by SNES), relaxed', gauss_legendre3)]
  end procedure registered_tableaux

  !> Classic RK4, order 4.
  module procedure classic_rk4
    call allocate_tableau(t, 'classic RK4', 4, 4)
    t%a(2, 1) = 0.5_real64
    t%a(3, 2) = 0.5_real64
    t%a(4, 3) = 1.0_real64
    t%b = [1.0_real64/6, 1.0_real64/3, 1.0_real64/3, 1.0_real64/6]
    t%c = row_sums(t%a)
  end procedure classic_rk4

  !> Cooper and Verner's method of order 8 with 11 stages (docs/integrators.md).
  module procedure cooper_verner8
    real(real64) :: r

    r = sqrt(21.0_real64)
    call allocate_tableau(t, 'Cooper-Verner 8', 11, 8)
    t%a(2, 1) = 0.5_real64
    t%a(3, 1:2) = [0.25_real64, 0.25_real64]
    t%a(4, 1:3) = [1.0_real64/7, (-7 + 3*r)/98, (21 - 5*r)/49]
    t%a(5, 1:4) = [(11 - r)/84, 0.0_real64, (18 - 4*r)/63, (21 + r)/252]
    t%a(6, 1:5) = [(5 - r)/48, 0.0_real64, (9 - r)/36, (-231 - 14*r)/360, (63 + 7*r)/80]
    t%a(7, 1:6) = [(10 + r)/42, 0.0_real64, (-432 - 92*r)/315, (633 + 145*r)/90, (-504 - 115*r)/70, (63 + 13*r)/35]
    t%a(8, 1:7) = [1.0_real64/14, 0.0_real64, 0.0_real64, 0.0_real64, (14 + 3*r)/126, (13 + 3*r)/63, 1.0_real64/9]
    t%a(9, 1:8) = [1.0_real64/32, 0.0_real64, 0.0_real64, 0.0_real64, (91 + 21*r)/576, 11.0_real64/72, &
                   (-385 + 75*r)/1152, (63 - 13*r)/128]
    t%a(10, 1:9) = [1.0_real64/14, 0.0_real64, 0.0_real64, 0.0_real64, 1.0_real64/9, (-733 + 147*r)/2205, &
                    (515 - 111*r)/504, (-51 + 11*r)/56, (132 - 28*r)/245]
    t%a(11, 1:10) = [0.0_real64, 0.0_real64, 0.0_real64, 0.0_real64, (-42 - 7*r)/18, (-18 - 28*r)/45, &
                     (-273 + 53*r)/72, (301 - 53*r)/72, (28 + 28*r)/45, (49 + 7*r)/18]
    t%b = [1.0_real64/20, 0.0_real64, 0.0_real64, 0.0_real64, 0.0_real64, 0.0_real64, 0.0_real64, &
           49.0_real64/180, 16.0_real64/45, 49.0_real64/180, 1.0_real64/20]
    t%c = row_sums(t%a)
  end procedure cooper_verner8

  !> Dormand and Prince's 8(5,3) pair: the order-8 weights and the error weights of DOP853.
  module procedure dormand_prince853
    real(real64) :: bhh(12)

    call allocate_tableau(t, 'Dormand-Prince 8(5,3)', 12, 8)
    t%a(2, 1) = 5.26001519587677318785587544488e-2_real64
    t%a(3, 1:2) = [1.97250569845378994544595329183e-2_real64, 5.91751709536136983633785987549e-2_real64]
    t%a(4, [1, 3]) = [2.95875854768068491816892993775e-2_real64, 8.87627564304205475450678981324e-2_real64]
    t%a(5, [1, 3, 4]) = [2.41365134159266685502369798665e-1_real64, -8.84549479328286085344864962717e-1_real64, &
                         9.24834003261792003115737966543e-1_real64]
    t%a(6, [1, 4, 5]) = [3.7037037037037037037037037037e-2_real64, 1.70828608729473871279604482173e-1_real64, &
                         1.25467687566822425016691814123e-1_real64]
    t%a(7, [1, 4, 5, 6]) = [3.7109375e-2_real64, 1.70252211019544039314978060272e-1_real64, &
                            6.02165389804559606850219397283e-2_real64, -1.7578125e-2_real64]
    t%a(8, [1, 4, 5, 6, 7]) = [3.70920001185047927108779319836e-2_real64, 1.70383925712239993810214054705e-1_real64, &
                               1.07262030446373284651809199168e-1_real64, -1.53194377486244017527936158236e-2_real64, &
                               8.27378916381402288758473766002e-3_real64]
    t%a(9, [1, 4, 5, 6, 7, 8]) = [6.24110958716075717114429577812e-1_real64, -3.36089262944694129406857109825e0_real64, &
                                  -8.68219346841726006818189891453e-1_real64, 2.75920996994467083049415600797e1_real64, &
                                  2.01540675504778934086186788979e1_real64, -4.34898841810699588477366255144e1_real64]
    t%a(10, [1, 4, 5, 6, 7, 8, 9]) = [4.77662536438264365890433908527e-1_real64, &
                                      -2.48811461997166764192642586468e0_real64, &
                                      -5.90290826836842996371446475743e-1_real64, &
                                      2.12300514481811942347288949897e1_real64, 1.52792336328824235832596922938e1_real64, &
                                      -3.32882109689848629194453265587e1_real64, &
                                      -2.03312017085086261358222928593e-2_real64]
    t%a(11, [1, 4, 5, 6, 7, 8, 9, 10]) = [-9.3714243008598732571704021658e-1_real64, &
                                          5.18637242884406370830023853209e0_real64, &
                                          1.09143734899672957818500254654e0_real64, &
                                          -8.14978701074692612513997267357e0_real64, &
                                          -1.85200656599969598641566180701e1_real64, &
                                          2.27394870993505042818970056734e1_real64, &
                                          2.49360555267965238987089396762e0_real64, &
                                          -3.0467644718982195003823669022e0_real64]
    t%a(12, [1, 4, 5, 6, 7, 8, 9, 10, 11]) = [2.27331014751653820792359768449e0_real64, &
                                              -1.05344954667372501984066689879e1_real64, &
                                              -2.00087205822486249909675718444e0_real64, &
                                              -1.79589318631187989172765950534e1_real64, &
                                              2.79488845294199600508499808837e1_real64, &
                                              -2.85899827713502369474065508674e0_real64, &
                                              -8.87285693353062954433549289258e0_real64, &
                                              1.23605671757943030647266201528e1_real64, &
                                              6.43392746015763530355970484046e-1_real64]
    t%b = 0.0_real64
    t%b([1, 6, 7, 8, 9, 10, 11, 12]) = [5.42937341165687622380535766363e-2_real64, 4.45031289275240888144113950566e0_real64, &
                                        1.89151789931450038304281599044e0_real64, -5.8012039600105847814672114227e0_real64, &
                                        3.1116436695781989440891606237e-1_real64, &
                                        -1.52160949662516078556178806805e-1_real64, &
                                        2.01365400804030348374776537501e-1_real64, 4.47106157277725905176885569043e-2_real64]
    t%c = row_sums(t%a)
    t%embedded = .true.
    allocate (t%e5(12), t%e3(12))
    t%e5 = 0.0_real64
    t%e5([1, 6, 7, 8, 9, 10, 11, 12]) = [0.1312004499419488073250102996e-01_real64, -0.1225156446376204440720569753e+01_real64, &
                                         -0.4957589496572501915214079952e+00_real64, &
                                         0.1664377182454986536961530415e+01_real64, &
                                         -0.3503288487499736816886487290e+00_real64, &
                                         0.3341791187130174790297318841e+00_real64, &
                                         0.8192320648511571246570742613e-01_real64, &
                                         -0.2235530786388629525884427845e-01_real64]
    ! The order-3 estimator is the order-8 weights minus a 3-stage formula.
    bhh = 0.0_real64
    bhh([1, 9, 12]) = [0.244094488188976377952755905512e+00_real64, 0.733846688281611857341361741547e+00_real64, &
                       0.220588235294117647058823529412e-01_real64]
    t%e3 = t%b - bhh
  end procedure dormand_prince853

  !> Gauss-Legendre collocation with 3 stages, order 6, at the zeros of the shifted Legendre
  !> polynomial of degree 3: c = 1/2 - sqrt(15)/10, 1/2, 1/2 + sqrt(15)/10.
  module procedure gauss_legendre3
    real(real64) :: r

    r = sqrt(15.0_real64)
    call allocate_tableau(t, 'Gauss-Legendre 3', 3, 6)
    t%implicit = .true.
    t%a(1, :) = [5.0_real64/36, 2.0_real64/9 - r/15, 5.0_real64/36 - r/30]
    t%a(2, :) = [5.0_real64/36 + r/24, 2.0_real64/9, 5.0_real64/36 - r/24]
    t%a(3, :) = [5.0_real64/36 + r/30, 2.0_real64/9 + r/15, 5.0_real64/36]
    t%b = [5.0_real64/18, 4.0_real64/9, 5.0_real64/18]
    t%c = [0.5_real64 - r/10, 0.5_real64, 0.5_real64 + r/10]
  end procedure gauss_legendre3

  pure subroutine allocate_tableau(t, name, stages, order)
    type(butcher_tableau), intent(inout) :: t
    character(len=*), intent(in) :: name
    integer, intent(in) :: stages, order

    t%name = name
    t%stages = stages
    t%order = order
    allocate (t%a(stages, stages), t%b(stages), t%c(stages))
    t%a = 0.0_real64
  end subroutine allocate_tableau

  pure function row_sums(a) result(c)
    real(real64), intent(in) :: a(:, :)
    real(real64) :: c(size(a, 1))

    c = sum(a, dim=2)
  end function row_sums

end submodule butcher_tableaux_lines
