!> The chain's mechanics as its model's overrides (src/model/spring_chain/spring_chain_model): T + V_g
!> of the masses, its gradient, difference and rounding scale, and the angular momentum J =
!> sum_i x_i x p_i with the components of it that are kept (docs/formulation.md section 10).
submodule (spring_chain_model) spring_chain_mechanics
  use model_interface, only: component_values
  use spring_chain_balance, only: mass_energy, mass_energy_difference, angular_momentum
  implicit none

contains

  module procedure mechanical_energy
    integer :: i, d

    d = self%layout%dimension
    energy = 0.0_real64
    do i = 1, self%layout%masses
      associate (k => self%layout%mass_indices(i))
        energy = energy + mass_energy(self%masses(i), self%gravity, z(k(1:d)), z(k(d + 1:)))
      end associate
    end do
  end procedure mechanical_energy

  module procedure mechanical_energy_gradient
    integer :: i, d

    d = self%layout%dimension
    gradient = 0.0_real64
    do i = 1, self%layout%masses
      associate (k => self%layout%mass_indices(i))
        gradient(k(1:d)) = -self%masses(i)*self%gravity
        gradient(k(d + 1:)) = z(k(d + 1:))/self%masses(i)
      end associate
    end do
  end procedure mechanical_energy_gradient

  module procedure chain_energy_difference
    integer :: i, d

    d = self%layout%dimension
    delta = 0.0_real64
    do i = 1, self%layout%masses
      associate (k => self%layout%mass_indices(i))
        delta = delta + mass_energy_difference(self%masses(i), self%gravity, z_a(k(1:d)), z_a(k(d + 1:)), &
                                               z_b(k(1:d)), z_b(k(d + 1:)))
      end associate
    end do
  end procedure chain_energy_difference

  module procedure mechanical_energy_scale
    integer :: i, d

    d = self%layout%dimension
    mechanical_energy_scale = 0.0_real64
    do i = 1, self%layout%masses
      associate (k => self%layout%mass_indices(i))
        mechanical_energy_scale = mechanical_energy_scale + sum(z(k(d + 1:))**2)/(2.0_real64*self%masses(i)) &
                                  + self%masses(i)*sum(abs(self%gravity*z(k(1:d))))
      end associate
    end do
  end procedure mechanical_energy_scale

  module procedure momentum_scale
    integer :: i, d

    d = self%layout%dimension
    momentum_scale = 0.0_real64
    do i = 1, self%layout%masses
      associate (k => self%layout%mass_indices(i))
        momentum_scale = momentum_scale + norm2(z(k(1:d)))*norm2(z(k(d + 1:)))
      end associate
    end do
  end procedure momentum_scale

  pure module function chain_angular_momentum(self, z) result(j)
    class(spring_chain), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: j(self%momentum_count())
    real(real64) :: total(3)
    integer :: i, d

    if (size(j) == 0) return
    d = self%layout%dimension
    total = 0.0_real64
    do i = 1, self%layout%masses
      associate (k => self%layout%mass_indices(i))
        total = total + angular_momentum(z(k(1:d)), z(k(d + 1:)))
      end associate
    end do
    if (size(j) == 3) then
      j = total
    else
      j = total(3)
    end if
  end function chain_angular_momentum

  pure module function conserved_in_momenta(self, momenta) result(values)
    class(spring_chain), intent(in) :: self
    real(real64), intent(in) :: momenta(:)
    real(real64) :: values(self%conserved_count())

    values = component_values(self%conserved, momenta)
  end function conserved_in_momenta

  pure module function conserved_momenta_gradient(self, z) result(gradients)
    class(spring_chain), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: gradients(size(z), self%conserved_count())
    real(real64) :: x(3), axis(3)
    integer :: i, d, k

    d = self%layout%dimension
    gradients = 0.0_real64
    do k = 1, size(gradients, 2)
      axis = self%conserved(k)%axis
      do i = 1, self%layout%masses
        associate (m => self%layout%mass_indices(i))
          x = 0.0_real64
          x(1:d) = z(m(1:d))
          ! a x x, of which the first d components are the p_i columns'.
          associate (a_cross_x => [axis(2)*x(3) - axis(3)*x(2), axis(3)*x(1) - axis(1)*x(3), &
                                   axis(1)*x(2) - axis(2)*x(1)])
            gradients(m(d + 1:), k) = a_cross_x(1:d)
          end associate
        end associate
      end do
    end do
  end function conserved_momenta_gradient

end submodule spring_chain_mechanics
