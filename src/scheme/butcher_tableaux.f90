!> Butcher tableaux of the relaxed Runge-Kutta family (docs/integrators.md): stages
!> g_i = z + h sum_j a_ij k_j, k_i = f(g_i), update z + h sum_i b_i k_i. Each is typed from its
!> source and checked by tests/unit/test_relaxed_runge_kutta (row sums c_i = sum_j a_ij, and the
!> order on problems with known solutions):
!>  - classic RK4;
!>  - Cooper and Verner's 11-stage method of order 8 (SIAM J. Numer. Anal. 9, 1972), every
!>    weight >= 0, in closed form with r = sqrt(21);
!>  - Dormand and Prince's 8(5,3) pair (Hairer, Norsett, Wanner, Solving ODEs I, code DOP853):
!>    12 stages of order 8 with two negative weights and embedded error estimators of orders 5
!>    and 3;
!>  - Gauss-Legendre collocation with 3 stages, order 6, implicit, all weights > 0.
!> Each is a relaxed integrator by one line of `registered_tableaux` (its name, label, description
!> and tableau); the integrator registry makes its row from it, with the capabilities the tableau
!> implies (embedded weights: adaptive at the tolerance; implicit: stages solved by SNES). The
!> table and the coefficients live in the submodule butcher_tableaux_lines, so that a new tableau
!> (its function and its line there) recompiles that file alone and relinks the programs.
module butcher_tableaux
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: butcher_tableau, classic_rk4, cooper_verner8, dormand_prince853, gauss_legendre3
  public :: tableau_entry, registered_tableaux, tableau_named

  !> A Runge-Kutta method; `implicit` when a has entries on or above the diagonal.
  type :: butcher_tableau
    character(len=24) :: name = ''
    integer :: stages = 0
    integer :: order = 0
    logical :: implicit = .false.
    real(real64), allocatable :: a(:, :), b(:), c(:)
    !> Embedded error weights (adaptive methods): error estimates h sum_i e5_i k_i (order 5)
    !> and h sum_i e3_i k_i (order 3), combined as in DOP853.
    logical :: embedded = .false.
    real(real64), allocatable :: e5(:), e3(:)
  end type butcher_tableau

  !> A relaxed Runge-Kutta integrator as data: &integrator scheme = name.
  type :: tableau_entry
    character(len=16) :: name = ''
    character(len=16) :: label = ''                 !! for figures
    character(len=100) :: description = ''
    procedure(tableau_maker), pointer, nopass :: make => null()
  end type tableau_entry

  abstract interface
    pure function tableau_maker() result(t)
      import :: butcher_tableau
      type(butcher_tableau) :: t
    end function tableau_maker
  end interface

  interface
    !> The relaxed integrators, a line each (the submodule butcher_tableaux_lines).
    pure module function registered_tableaux() result(entries)
      type(tableau_entry), allocatable :: entries(:)
    end function registered_tableaux
    !> Classic RK4, order 4.
    pure module function classic_rk4() result(t)
      type(butcher_tableau) :: t
    end function classic_rk4
    !> Cooper and Verner's method of order 8 with 11 stages (docs/integrators.md).
    pure module function cooper_verner8() result(t)
      type(butcher_tableau) :: t
    end function cooper_verner8
    !> Dormand and Prince's 8(5,3) pair (DOP853), with its embedded estimators.
    pure module function dormand_prince853() result(t)
      type(butcher_tableau) :: t
    end function dormand_prince853
    !> Gauss-Legendre collocation with 3 stages, order 6.
    pure module function gauss_legendre3() result(t)
      type(butcher_tableau) :: t
    end function gauss_legendre3
  end interface

contains

  !> The tableau of the relaxed integrator `name`; found = .false. if there is none.
  subroutine tableau_named(name, tableau, found)
    character(len=*), intent(in) :: name
    type(butcher_tableau), intent(out) :: tableau
    logical, intent(out) :: found
    type(tableau_entry), allocatable :: entries(:)
    integer :: i

    allocate (entries, source=registered_tableaux())
    found = .false.
    do i = 1, size(entries)
      if (trim(entries(i)%name) /= trim(name)) cycle
      tableau = entries(i)%make()
      found = .true.
      return
    end do
  end subroutine tableau_named

end module butcher_tableaux
