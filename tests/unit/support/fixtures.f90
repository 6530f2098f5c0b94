!> Shared helpers for the unit tests: reproducible random states near the paper's scene and
!> central-difference checks of analytic derivatives (tolerance ~ sqrt(epsilon), CONVENTIONS).
module fixtures
  use, intrinsic :: iso_fortran_env, only: real64
  use funit, only: assertTrue
  use close_values, only: is_close, closeness
  use invariant_function, only: invariant_functions
  use model_parameters, only: pendulum_parameters
  use paper_free_energy, only: paper_psi
  use pendulum_model, only: pendulum
  use double_pendulum, only: state_size
  use nonlinear_problem, only: nonlinear_system
  implicit none (type, external)
  private
  public :: seed_random, uniform, paper_state, random_state, check_derivatives, fd_jacobian_error
  public :: paper_legendre, quadratic_pair

  !> f(x) = 1/2 x.A x + c.x for two fixed (A, c): a test function with a known discrete gradient.
  type, extends(invariant_functions) :: quadratic_pair
    real(real64) :: a(3, 3, 2), c(3, 2)
  contains
    procedure :: evaluate => evaluate_quadratic
  end type quadratic_pair

contains

  !> Makes random_number reproducible.
  subroutine seed_random(seed)
    integer, intent(in) :: seed
    integer :: n
    integer, allocatable :: values(:)

    call random_seed(size=n)
    allocate (values(n))
    values = seed + 7919*[(n, n=1, size(values))]
    call random_seed(put=values)
  end subroutine seed_random

  !> A uniform random number in [low, high).
  function uniform(low, high) result(x)
    real(real64), intent(in) :: low, high
    real(real64) :: x

    call random_number(x)
    x = low + (high - low)*x
  end function uniform

  !> The paper's initial state (docs/formulation.md section 1) in the model's thermodynamic variable.
  function paper_state(model) result(z)
    type(pendulum), intent(in) :: model
    real(real64) :: z(state_size)
    integer :: stat

    call model%state_from_temperatures([1.0_real64, 0.0_real64, 0.0_real64], [3.0_real64, 0.0_real64, 0.0_real64], &
                                       [0.0_real64, 0.0_real64, 0.0_real64], [-1.0_real64, -1.0_real64, 0.0_real64], &
                                       0.0_real64, [280.0_real64, 350.0_real64], z, stat)
    if (stat /= 0) error stop 'fixtures: paper state outside the domain'
  end function paper_state

  !> A random state: positions, momenta and gamma of paper-scene size, temperatures in [250, 400] K.
  function random_state(model) result(z)
    type(pendulum), intent(in) :: model
    real(real64) :: z(state_size)
    real(real64) :: q1(3), q2(3), p1(3), p2(3), gamma, theta(2)
    integer :: i, stat

    do i = 1, 3
      q1(i) = uniform(-1.5_real64, 1.5_real64)
      q2(i) = uniform(-2.5_real64, 2.5_real64)
      p1(i) = uniform(-3.0_real64, 3.0_real64)
      p2(i) = uniform(-3.0_real64, 3.0_real64)
    end do
    q1(1) = q1(1) + sign(0.8_real64, q1(1))   ! keep the springs away from zero length
    q2(1) = q2(1) + sign(1.0_real64, q2(1))
    gamma = uniform(-0.3_real64, 0.3_real64)
    theta = [uniform(250.0_real64, 400.0_real64), uniform(250.0_real64, 400.0_real64)]
    call model%state_from_temperatures(q1, q2, p1, p2, gamma, theta, z, stat)
    if (stat /= 0) error stop 'fixtures: random state outside the domain'
  end function random_state

  !> Checks grad and Hessian of `fun` at x against central differences with steps h(:).
  subroutine check_derivatives(name, fun, x, h, k)
    character(len=*), intent(in) :: name
    class(invariant_functions), intent(in) :: fun
    real(real64), intent(in) :: x(:), h(:)
    integer, intent(in) :: k
    real(real64) :: f(k), g(size(x), k), hess(size(x), size(x), k)
    real(real64) :: fp(k), fm(k), gp(size(x), k), gm(size(x), k), fd_g(size(x), k), fd_h(size(x), size(x), k)
    real(real64) :: xp(size(x)), xm(size(x))
    integer :: i, stat

    call fun%evaluate(x, f, g, hess, stat)
    do i = 1, size(x)
      xp = x
      xm = x
      xp(i) = x(i) + h(i)
      xm(i) = x(i) - h(i)
      call fun%evaluate(xp, fp, gp, stat=stat)
      call fun%evaluate(xm, fm, gm, stat=stat)
      fd_g(i, :) = (fp - fm)/(2*h(i))
      fd_h(:, i, :) = (gp - gm)/(2*h(i))
    end do
    call assertTrue(is_close(reshape(g, [size(g)]), reshape(fd_g, [size(g)]), 1.0e-6_real64, &
                             1.0e-7_real64*maxval(abs(g))), name//' gradient: '// &
                    closeness(reshape(g, [size(g)]), reshape(fd_g, [size(g)]), 1.0e-6_real64, 1.0e-7_real64*maxval(abs(g))))
    call assertTrue(is_close(reshape(hess, [size(hess)]), reshape(fd_h, [size(hess)]), 1.0e-6_real64, &
                             1.0e-7_real64*maxval(abs(hess))), name//' Hessian: '// &
                    closeness(reshape(hess, [size(hess)]), reshape(fd_h, [size(hess)]), 1.0e-6_real64, &
                              1.0e-7_real64*maxval(abs(hess))))
  end subroutine check_derivatives

  !> Largest entry of |J - J_fd| / (1 + |J|), J_fd by central differences of the problem's
  !> residual with steps h(:): 2nd order by default, 4th order if fourth_order is true.
  function fd_jacobian_error(problem, x, jacobian, h, fourth_order) result(err)
    class(nonlinear_system), intent(in) :: problem
    real(real64), intent(in) :: x(:), jacobian(:, :), h(:)
    logical, intent(in), optional :: fourth_order
    real(real64) :: err
    real(real64) :: column(size(jacobian, 1))
    integer :: j
    logical :: high

    high = .false.
    if (present(fourth_order)) high = fourth_order
    err = 0.0_real64
    do j = 1, size(x)
      if (high) then
        column = (-shifted(j, 2*h(j)) + 8*shifted(j, h(j)) - 8*shifted(j, -h(j)) + shifted(j, -2*h(j)))/(12*h(j))
      else
        column = (shifted(j, h(j)) - shifted(j, -h(j)))/(2*h(j))
      end if
      err = max(err, maxval(abs(column - jacobian(:, j))/(1.0_real64 + abs(jacobian(:, j)))))
    end do

  contains

    function shifted(j, step) result(r)
      integer, intent(in) :: j
      real(real64), intent(in) :: step
      real(real64) :: r(size(jacobian, 1)), xs(size(x))
      integer :: stat

      xs = x
      xs(j) = x(j) + step
      call problem%evaluate(xs, r, stat=stat)
    end function shifted
  end function fd_jacobian_error

  !> s and u of spring a from psi exactly as the paper writes it (16)-(17):
  !> s = -d psi/d theta by a 4th-order central difference, u = psi + theta s.
  subroutine paper_legendre(params, a, length, theta, gamma, s, u)
    type(pendulum_parameters), intent(in) :: params
    integer, intent(in) :: a
    real(real64), intent(in) :: length, theta, gamma
    real(real64), intent(out) :: s, u
    real(real64) :: h

    h = 1.0e-3_real64*theta
    s = -(-paper_psi(params, a, length, theta + 2*h, gamma) &
          + 8*paper_psi(params, a, length, theta + h, gamma) &
          - 8*paper_psi(params, a, length, theta - h, gamma) &
          + paper_psi(params, a, length, theta - 2*h, gamma))/(12*h)
    u = paper_psi(params, a, length, theta, gamma) + theta*s
  end subroutine paper_legendre

  pure subroutine evaluate_quadratic(self, x, f, grad, hess, stat)
    class(quadratic_pair), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: f(:), grad(:, :)
    real(real64), intent(out), optional :: hess(:, :, :)
    integer, intent(out) :: stat
    integer :: j

    do j = 1, 2
      grad(:, j) = matmul(self%a(:, :, j), x) + self%c(:, j)
      f(j) = 0.5_real64*dot_product(x, matmul(self%a(:, :, j), x)) + dot_product(self%c(:, j), x)
      if (present(hess)) hess(:, :, j) = self%a(:, :, j)
    end do
    stat = 0
  end subroutine evaluate_quadratic

end module fixtures
