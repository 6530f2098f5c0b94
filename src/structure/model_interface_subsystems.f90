!> What generic_model's defaults take from its subsystems' potentials (src/structure/model_interface):
!> E and S and their differences, the temperatures, the exact partials and the continuous field, the
!> chain rule through the partials, and a state in another thermodynamic variable.
submodule (model_interface) model_interface_subsystems
  use failures, only: domain_overflow
  implicit none

contains

  module procedure energy_difference
    real(real64) :: x_a(self%max_invariants), x_b(self%max_invariants), part(2)
    integer :: a, n

    delta = self%mechanical_energy_difference(z_a, z_b)
    if (present(entropy_delta)) entropy_delta = 0.0_real64
    stat = failure_none
    do a = 1, size(self%subsystems)
      n = self%subsystems(a)%invariant_count
      call self%invariants(z_a, a, x_a(1:n))
      call self%invariants(z_b, a, x_b(1:n))
      call self%subsystems(a)%potentials%difference(x_a(1:n), x_b(1:n), part, stat)
      if (stat /= failure_none) return
      delta = delta + part(potential_u)
      if (present(entropy_delta)) entropy_delta = entropy_delta + part(potential_s)
    end do
  end procedure energy_difference

  module procedure convert_state
    real(real64) :: x(self%max_invariants), theta
    integer :: a, n

    z_target = z
    stat = failure_none
    do a = 1, size(self%subsystems)
      if (self%subsystems(a)%tau_column == 0) cycle
      n = self%subsystems(a)%invariant_count
      call self%invariants(z, a, x(1:n))
      call self%subsystems(a)%potentials%temperature(x(1:n), theta, stat)
      if (stat /= failure_none) return
      call target%subsystems(a)%potentials%tau_from_temperature(x(1:n - 1), theta, &
                                                                z_target(self%subsystems(a)%tau_column), stat)
      if (stat /= failure_none) return
    end do
  end procedure convert_state

  module procedure observe
    real(real64) :: f(2), x(self%max_invariants), g(self%max_invariants, 2), u_scale, s_scale, scales(2)
    integer :: a, n

    energy = self%mechanical_energy(z)
    entropy = 0.0_real64
    temperature = 0.0_real64
    u_scale = 0.0_real64
    s_scale = 0.0_real64
    stat = failure_none
    do a = 1, size(self%subsystems)
      n = self%subsystems(a)%invariant_count
      call self%invariants(z, a, x(1:n))
      if (self%subsystems(a)%tau_column > 0) then
        call self%subsystems(a)%potentials%values_and_temperature(x(1:n), f, temperature(a), stat, scales)
      else
        call self%subsystems(a)%potentials%evaluate(x(1:n), f, g(1:n, :), stat=stat)
        scales = abs(f)
      end if
      if (stat /= failure_none) return
      energy = energy + f(potential_u)
      entropy = entropy + f(potential_s)
      u_scale = u_scale + scales(potential_u)
      s_scale = s_scale + scales(potential_s)
    end do
    if (present(energy_scale)) energy_scale = self%mechanical_energy_scale(z) + u_scale
    if (present(entropy_scale)) entropy_scale = s_scale
  end procedure observe

  module procedure temperatures
    real(real64) :: x(self%max_invariants)
    integer :: a, n

    theta = 0.0_real64
    which = 0
    stat = failure_none
    do a = 1, self%temperature_count()
      n = self%subsystems(a)%invariant_count
      call self%invariants(z, a, x(1:n))
      call self%subsystems(a)%potentials%temperature(x(1:n), theta(a), stat)
      if (stat /= failure_none) then
        which = a
        return
      end if
    end do
  end procedure temperatures

  module procedure exact_partials
    real(real64) :: f(2), g(self%max_invariants, 2), h(self%max_invariants, self%max_invariants, 2)
    real(real64) :: x(self%max_invariants), dx(self%max_invariants, self%state_size)
    integer :: a, n, m

    partials = 0.0_real64
    stat = failure_none
    if (present(dpartials_dz)) dpartials_dz = 0.0_real64
    do a = 1, size(self%subsystems)
      associate (part => self%subsystems(a))
        n = part%invariant_count
        m = size(part%columns)
        if (present(dpartials_dz)) then
          call self%invariants(z, a, x(1:n), dx(1:n, 1:m))
          call part%potentials%evaluate(x(1:n), f, g(1:n, :), h(1:n, 1:n, :), stat)
        else
          call self%invariants(z, a, x(1:n))
          call part%potentials%evaluate(x(1:n), f, g(1:n, :), stat=stat)
        end if
        if (stat /= failure_none) return
        partials(1:n, :, a) = g(1:n, :)
        if (present(dpartials_dz)) call self%chain_to_state(a, h(1:n, 1:n, :), dx(1:n, 1:m), dpartials_dz)
      end associate
    end do
  end procedure exact_partials

  module procedure continuous_field
    real(real64) :: partials(self%max_invariants, 2, size(self%subsystems))
    ! Allocated, and only for the Jacobian: each is 6 x subsystems x state_size numbers, 12 MB for
    ! a chain of 1000 unknowns, beyond a default stack.
    real(real64), allocatable :: dpartials(:, :, :, :), df_dpartials(:, :, :, :)

    if (present(jacobian)) then
      allocate (dpartials(self%max_invariants, 2, size(self%subsystems), self%state_size), &
                df_dpartials(self%state_size, self%max_invariants, 2, size(self%subsystems)))
      call self%exact_partials(z, partials, dpartials, stat)
      if (stat /= failure_none) return
      call self%vector_field(z, partials, f, jacobian, df_dpartials)
      call self%add_partials_chain(df_dpartials, dpartials, 1.0_real64, jacobian)
    else
      call self%exact_partials(z, partials, stat=stat)
      if (stat /= failure_none) return
      call self%vector_field(z, partials, f)
    end if
    if (.not. all(abs(f) <= huge(1.0_real64))) stat = domain_overflow
  end procedure continuous_field

  module procedure chain_to_state
    integer :: i, k, j

    associate (columns => self%subsystems(a)%columns)
      do k = 1, 2
        do i = 1, size(dg, 1)
          do j = 1, size(columns)
            dpartials_dz(i, k, a, columns(j)) = dot_product(dg(i, :, k), dx_dz(:, j))
          end do
        end do
      end do
    end associate
  end procedure chain_to_state

  module procedure add_partials_chain
    integer :: a, k, i, j, column

    do a = 1, size(self%subsystems)
      associate (part => self%subsystems(a))
        do j = 1, size(part%columns)
          column = part%columns(j)
          do k = 1, 2
            do i = 1, part%invariant_count
              jacobian(1:self%state_size, column) = jacobian(1:self%state_size, column) &
                + factor*dpartials_dz(i, k, a, column)*df_dpartials(:, i, k, a)
            end do
          end do
        end do
      end associate
    end do
  end procedure add_partials_chain

  module procedure subsystem_gradient
    real(real64) :: x(self%max_invariants), dx(self%max_invariants, self%state_size)
    integer :: a, n, m

    gradient = 0.0_real64
    do a = 1, size(self%subsystems)
      n = self%subsystems(a)%invariant_count
      m = size(self%subsystems(a)%columns)
      call self%invariants(z, a, x(1:n), dx(1:n, 1:m))
      gradient(self%subsystems(a)%columns) = gradient(self%subsystems(a)%columns) &
                                             + matmul(partials(1:n, potential, a), dx(1:n, 1:m))
    end do
  end procedure subsystem_gradient

end submodule model_interface_subsystems
