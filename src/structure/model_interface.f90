!> What a model must provide for the time integrators: a GENERIC system with Mielke's split
!> (paper eqs. (4)-(12), docs/formulation.md section 4) made of thermodynamic subsystems.
!>
!> The state z has `state_size` entries. Subsystem a owns a pair of potentials (U_a, S_a) as
!> functions of its invariants x_a(z) = (mechanical invariants, tau_a): tau_a is the subsystem's
!> thermodynamic variable, a column of z, and the last invariant. E = mechanical energy (kinetic,
!> gravity) + sum U_a, S = sum S_a. The schemes never differentiate U_a and S_a in z directly:
!> they take `partials(i, k, a)`, the derivative of potential k (potential_u or potential_s) of
!> subsystem a in its invariant i (1..n_a, tau last) -- exact ones at a state, or discrete
!> gradients between two states -- and hand them to the model's written-out vector field
!> f(z, partials) = L grad E + K grad S. For EME to conserve E and J exactly, a model's mechanical
!> invariants must be at most quadratic in z (their midpoint gradient is then exact).
!>
!> A new model extends `generic_model`: it fills `state_size`, `column_names` and `subsystems`
!> when it is built, implements the deferred procedures and says its columns' units
!> (`column_units`, 'unknown' by default). It describes itself to the output (`words`) and
!> declares its momenta, if it has any (`momentum_names`, `momenta`), and the components of them
!> that are first integrals (`conserved`: each with its name and axis; `conserved_in_momenta` and
!> their gradients in the momenta; `angular_momentum_components` gives those of an angular
!> momentum under gravity, docs/formulation.md section 2); a model without momenta has no momentum
!> dataset, and one without conserved components no drift figure and no momentum in the relaxed
!> schemes' projection. Everything else here is generic.
module model_interface
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: invariant_functions, potential_u, potential_s
  use failures, only: failure_none
  implicit none (type, external)
  private
  public :: generic_model, subsystem, model_words, conserved_component, add_temperature_chain, model_step_figure
  public :: angular_momentum_components, component_values

  !> One thermodynamic subsystem (a spring, with its temperature). The model's builder sets every
  !> component.
  type :: subsystem
    character(len=16) :: name                                !! for messages, e.g. 'spring 1'
    class(invariant_functions), allocatable :: potentials   !! (U_a, S_a) of the invariants x_a
    integer :: invariant_count                               !! n_a, tau_a being the last
    integer, allocatable :: columns(:)                       !! the columns of z that x_a depends on
    integer :: tau_column                                    !! tau_a's column of z; 0: no thermodynamic variable
    real(real64), allocatable :: metric_scale(:)             !! typical sizes of x_a (docs/formulation.md section 5)
  end type subsystem

  !> How the output and the messages describe a model (docs/output.md); generic by default.
  type :: model_words
    character(len=120) :: temperature = 'temperatures theta_a = dU_a/dS_a of the subsystems'
    character(len=120) :: energy = 'total energy E: the mechanical energy and the subsystems'' U_a'
    character(len=120) :: entropy = 'total entropy S: the sum of the subsystems'' S_a'
    character(len=120) :: momenta = ''           !! the momentum dataset's description
    character(len=16) :: momentum_units = ''
    character(len=16) :: energy_units = 'J'       !! of E, V, heat and U_a
    character(len=16) :: entropy_units = 'J/K'    !! of S and S_a
    character(len=16) :: temperature_units = 'K'
    !> What the nondimensional metric of the discrete gradients divides each invariant by.
    character(len=160) :: metric_scales = 'each invariant by its typical size (attributes metric_scale_*)'
  end type model_words

  !> A component of the momenta that is a first integral, such as the angular momentum about the
  !> axis of gravity: its name (a column of the momentum dataset, or a name of its own such as J_g)
  !> and, for a component of an angular momentum, its unit axis in space.
  type :: conserved_component
    character(len=8) :: name = ''
    real(real64) :: axis(3) = 0.0_real64
  end type conserved_component

  !> A figure of each step that a model adds to a run's rows (a chain's smallest entropy
  !> production of a viscous branch): its dataset's name, units and description, and how strided
  !> rows combine it ('min', 'max', 'sum', 'mean', 'last').
  type :: model_step_figure
    character(len=32) :: name = '', units = '', combine = 'last'
    character(len=:), allocatable :: description
  end type model_step_figure

  !> A GENERIC model with Mielke's split.
  type, abstract :: generic_model
    type(model_words) :: words
    !> The columns of the momentum dataset (angular_momentum); none: the model has no momenta.
    character(len=8), allocatable :: momentum_names(:)
    !> The components of the momenta that are first integrals, in the order of conserved_momenta
    !> (their drifts are reported, the relaxed schemes keep each, the step check measures each);
    !> none: unallocated or empty; at most three (those of an angular momentum).
    type(conserved_component), allocatable :: conserved(:)
    integer :: state_size = 0
    integer :: thermo_variable = 0                           !! thermo_variable's tau_* of every subsystem
    character(len=16), allocatable :: column_names(:)        !! of z, in the model's thermodynamic variable
    type(subsystem), allocatable :: subsystems(:)
    integer :: max_invariants = 0                            !! the largest n_a, the first extent of partials
  contains
    procedure(invariants_interface), deferred :: invariants
    procedure(vector_field_interface), deferred :: vector_field
    procedure(scalar_of_state), deferred :: mechanical_energy
    procedure(vector_of_state), deferred :: mechanical_energy_gradient
    procedure(poisson_interface), deferred :: poisson_matrix_0
    procedure :: friction_matrix_0_at
    procedure :: friction_matrix_0
    procedure(in_variable_interface), deferred :: in_variable
    procedure :: conserved_count
    procedure :: conserved_momenta
    procedure :: conserved_in_momenta
    procedure :: conserved_momenta_gradient
    procedure :: momenta
    procedure :: momentum_count
    procedure :: mechanical_energy_difference
    procedure :: mechanical_energy_scale
    procedure :: momentum_scale
    procedure :: energy_difference
    procedure :: convert_state
    procedure :: subsystem_count
    procedure :: temperature_count
    procedure :: column_units
    procedure :: observe
    procedure :: temperatures
    procedure :: exact_partials
    procedure :: continuous_field
    procedure :: chain_to_state
    procedure :: add_partials_chain
    procedure :: subsystem_gradient
    procedure :: partials_temperatures
    procedure :: step_figure_list
    procedure :: step_figures
  end type generic_model

  abstract interface
    !> x_a(z), and optionally dx_dz(i, j) = d x_a(i)/d z(columns(j)).
    pure subroutine invariants_interface(self, z, a, x, dx_dz)
      import :: generic_model, real64
      class(generic_model), intent(in) :: self
      real(real64), intent(in) :: z(:)
      integer, intent(in) :: a
      real(real64), intent(out) :: x(:)
      real(real64), intent(out), optional :: dx_dz(:, :)
    end subroutine invariants_interface

    !> f(z, partials) = L grad E + K grad S written out, and optionally df/dz at fixed partials
    !> and df/dpartials(:, i, k, a).
    pure subroutine vector_field_interface(self, z, partials, f, df_dz, df_dpartials)
      import :: generic_model, real64
      class(generic_model), intent(in) :: self
      real(real64), intent(in) :: z(:), partials(:, :, :)
      real(real64), intent(out) :: f(:)
      real(real64), intent(out), optional :: df_dz(:, :), df_dpartials(:, :, :, :)
    end subroutine vector_field_interface

    !> The same model in thermodynamic variable `variable` (thermo_variable's tau_*).
    subroutine in_variable_interface(self, variable, other)
      import :: generic_model
      class(generic_model), intent(in) :: self
      integer, intent(in) :: variable
      class(generic_model), allocatable, intent(out) :: other
    end subroutine in_variable_interface

    !> A scalar function of the state: the mechanical energy (kinetic and gravity).
    pure function scalar_of_state(self, z) result(value)
      import :: generic_model, real64
      class(generic_model), intent(in) :: self
      real(real64), intent(in) :: z(:)
      real(real64) :: value
    end function scalar_of_state

    !> A gradient in z: of the mechanical energy.
    pure function vector_of_state(self, z) result(gradient)
      import :: generic_model, real64
      class(generic_model), intent(in) :: self
      real(real64), intent(in) :: z(:)
      real(real64) :: gradient(size(z))
    end function vector_of_state

    !> L0 of eq. (8): the Poisson matrix of the split, in z's layout.
    pure function poisson_interface(self) result(l0)
      import :: generic_model, real64
      class(generic_model), intent(in) :: self
      real(real64) :: l0(self%state_size, self%state_size)
    end function poisson_interface
  end interface

  ! Implemented in model_interface_subsystems.
  interface
    !> E(z_b) - E(z_a) without cancellation: the mechanical part by mechanical_energy_difference,
    !> the subsystems' U_a by their potentials' difference (relaxation solves E(z_b) = E(z_a));
    !> optionally S(z_b) - S(z_a) likewise.
    pure module subroutine energy_difference(self, z_a, z_b, delta, stat, entropy_delta)
      class(generic_model), intent(in) :: self
      real(real64), intent(in) :: z_a(:), z_b(:)
      real(real64), intent(out) :: delta
      integer, intent(out) :: stat
      real(real64), intent(out), optional :: entropy_delta
    end subroutine energy_difference

    !> The same physical state in `target`'s thermodynamic variable: every subsystem's tau from its
    !> temperature at the same mechanical invariants (docs/formulation.md section 3's closed forms).
    pure module subroutine convert_state(self, z, target, z_target, stat)
      class(generic_model), intent(in) :: self
      real(real64), intent(in) :: z(:)
      class(generic_model), intent(in) :: target
      real(real64), intent(out) :: z_target(:)
      integer, intent(out) :: stat
    end subroutine convert_state

    !> Total energy E (6), total entropy S and the subsystems' temperatures (2) at z; optionally
    !> the rounding scales of E and S (src/structure/step_balances): the mechanical energy's
    !> (mechanical_energy_scale) plus sum_a scale(U_a), and sum_a scale(S_a): the potentials' own
    !> rounding scales (invariant_function's values_and_temperature; |U_a| and |S_a| where there is
    !> no temperature).
    pure module subroutine observe(self, z, energy, entropy, temperature, stat, energy_scale, entropy_scale)
      class(generic_model), intent(in) :: self
      real(real64), intent(in) :: z(:)
      real(real64), intent(out) :: energy, entropy, temperature(:)
      integer, intent(out) :: stat
      real(real64), intent(out), optional :: energy_scale, entropy_scale
    end subroutine observe

    !> The subsystems' temperatures at z; stat reports the first that is outside the domain in
    !> `which` (0 if none).
    pure module subroutine temperatures(self, z, theta, stat, which)
      class(generic_model), intent(in) :: self
      real(real64), intent(in) :: z(:)
      real(real64), intent(out) :: theta(:)
      integer, intent(out) :: stat, which
    end subroutine temperatures

    !> The exact partials of U_a and S_a in each subsystem's invariants at z, and optionally their
    !> derivatives dpartials_dz(i, k, a, j) with respect to z(j).
    pure module subroutine exact_partials(self, z, partials, dpartials_dz, stat)
      class(generic_model), intent(in) :: self
      real(real64), intent(in) :: z(:)
      real(real64), intent(out) :: partials(:, :, :)
      real(real64), intent(out), optional :: dpartials_dz(:, :, :, :)
      integer, intent(out) :: stat
    end subroutine exact_partials

    !> The continuous field f(z) = L grad E + K grad S (eq. (8)) at the exact partials, and
    !> optionally its Jacobian df/dz (through the partials by the chain rule); stat /= failure_none
    !> outside the model's domain or where f is not finite.
    pure module subroutine continuous_field(self, z, f, stat, jacobian)
      class(generic_model), intent(in) :: self
      real(real64), intent(in) :: z(:)
      real(real64), intent(out) :: f(:)
      integer, intent(out) :: stat
      real(real64), intent(out), optional :: jacobian(:, :)
    end subroutine continuous_field

    !> Subsystem a's partials' derivatives in z from those in its invariants:
    !> dpartials_dz(i, k, a, columns(j)) = sum_l dg(i, l, k) dx_dz(l, j). Other columns are left alone.
    pure module subroutine chain_to_state(self, a, dg, dx_dz, dpartials_dz)
      class(generic_model), intent(in) :: self
      integer, intent(in) :: a
      real(real64), intent(in) :: dg(:, :, :), dx_dz(:, :)
      real(real64), intent(inout) :: dpartials_dz(:, :, :, :)
    end subroutine chain_to_state

    !> jacobian(:, j) += factor sum df_dpartials(:, i, k, a) dpartials_dz(i, k, a, j): the chain rule
    !> through the partials, over each subsystem's own invariants and columns (the rest is zero).
    pure module subroutine add_partials_chain(self, df_dpartials, dpartials_dz, factor, jacobian)
      class(generic_model), intent(in) :: self
      real(real64), intent(in) :: df_dpartials(:, :, :, :), dpartials_dz(:, :, :, :), factor
      real(real64), intent(inout) :: jacobian(:, :)
    end subroutine add_partials_chain

    !> The gradient in z of sum_a H_a (H = U if potential = potential_u, S if potential_s) from the
    !> partials: (dx_a/dz)^T partials(:, potential, a), with dx_a/dz at z.
    pure module function subsystem_gradient(self, z, partials, potential) result(gradient)
      class(generic_model), intent(in) :: self
      real(real64), intent(in) :: z(:), partials(:, :, :)
      integer, intent(in) :: potential
      real(real64) :: gradient(self%state_size)
    end function subsystem_gradient
  end interface

contains

  !> K0 of eq. (8) at the state z and the temperatures the partials give (eq. (2)), in z's
  !> layout: what the structure (structure_matrices) takes. A scheme evaluates it where it
  !> evaluates the field, at z_mid with the step's partials (docs/formulation.md section 5). By
  !> default the friction_matrix_0 of the partials alone; a model whose K0 depends on the state
  !> (the heat bath's drag on the velocity p/m, docs/formulation.md section 11) overrides this one.
  !> The field's df/dz then holds dK0/dz, as its df/dpartials holds dK0/dpartials.
  pure function friction_matrix_0_at(self, z, partials) result(k0)
    class(generic_model), intent(in) :: self
    real(real64), intent(in) :: z(:), partials(:, :, :)
    real(real64) :: k0(self%state_size, self%state_size)

    k0 = self%friction_matrix_0(partials)
  end function friction_matrix_0_at

  !> K0 of a model whose friction does not depend on the state: at the temperatures the partials
  !> give. Zero by default (no dissipation); a model overrides this one or friction_matrix_0_at.
  pure function friction_matrix_0(self, partials) result(k0)
    class(generic_model), intent(in) :: self
    real(real64), intent(in) :: partials(:, :, :)
    real(real64) :: k0(self%state_size, self%state_size)

    k0 = 0.0_real64
  end function friction_matrix_0

  !> The momenta the output records, in the order of momentum_names; none by default.
  pure function momenta(self, z) result(values)
    class(generic_model), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: values(self%momentum_count())

    values = 0.0_real64
  end function momenta

  !> The number of momenta the model declares (0: none).
  pure integer function momentum_count(self)
    class(generic_model), intent(in) :: self

    momentum_count = 0
    if (allocated(self%momentum_names)) momentum_count = size(self%momentum_names)
  end function momentum_count

  !> The number of conserved momentum components (0: none).
  pure integer function conserved_count(self)
    class(generic_model), intent(in) :: self

    conserved_count = 0
    if (allocated(self%conserved)) conserved_count = size(self%conserved)
  end function conserved_count

  !> The conserved components' values at z, in the order of `conserved`: those of the momenta
  !> there (conserved_in_momenta).
  pure function conserved_momenta(self, z) result(values)
    class(generic_model), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: values(self%conserved_count())

    values = self%conserved_in_momenta(self%momenta(z))
  end function conserved_momenta

  !> The conserved components' values, in the order of `conserved`, from the momenta (`momenta`'s
  !> values, in the order of momentum_names), each linear in them; none by default (a model with
  !> components overrides this). So a caller that has the momenta need not compute them again.
  pure function conserved_in_momenta(self, momenta) result(values)
    class(generic_model), intent(in) :: self
    real(real64), intent(in) :: momenta(:)
    real(real64) :: values(self%conserved_count())

    values = 0.0_real64
  end function conserved_in_momenta

  !> gradients(:, k): the derivative of component k in the momenta, zero in every other column of z
  !> (the directions in which the relaxed schemes' projection moves the momenta); none by default.
  pure function conserved_momenta_gradient(self, z) result(gradients)
    class(generic_model), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: gradients(size(z), self%conserved_count())

    gradients = 0.0_real64
  end function conserved_momenta_gradient

  !> The components of an angular momentum J (about a fixed point, in space) that a uniform
  !> gravity g leaves conserved (docs/formulation.md section 2): all three, J_x, J_y and J_z,
  !> without gravity; else the one along g: named J_x, J_y or J_z with that coordinate axis when g
  !> lies along one (either sign), or J_g with the axis g/|g|.
  pure function angular_momentum_components(gravity) result(components)
    real(real64), intent(in) :: gravity(3)
    type(conserved_component), allocatable :: components(:)
    integer :: i

    if (.not. any(abs(gravity) > 0.0_real64)) then
      components = [(about_coordinate_axis(i), i=1, 3)]
    else if (count(abs(gravity) > 0.0_real64) == 1) then
      components = [about_coordinate_axis(maxloc(abs(gravity), 1))]
    else
      components = [conserved_component('J_g', gravity/norm2(gravity))]
    end if

  contains

    ! J_x, J_y or J_z (i = 1, 2, 3) with its unit axis.
    pure function about_coordinate_axis(i) result(component)
      integer, intent(in) :: i
      type(conserved_component) :: component

      component%name = 'J_'//'xyz'(i:i)
      component%axis = 0.0_real64
      component%axis(i) = 1.0_real64
    end function about_coordinate_axis
  end function angular_momentum_components

  !> The components' values J.axis of an angular momentum j: its three components in space (in the
  !> order x, y, z of the sum, as the run file's readers take them from its columns), or in the
  !> plane its one component, about the normal z (the axis of a planar model's components).
  pure function component_values(components, j) result(values)
    type(conserved_component), intent(in) :: components(:)
    real(real64), intent(in) :: j(:)
    real(real64) :: values(size(components))
    integer :: k

    do k = 1, size(components)
      if (size(j) == 1) then
        values(k) = j(1)*components(k)%axis(3)
      else
        values(k) = j(1)*components(k)%axis(1) + j(2)*components(k)%axis(2) + j(3)*components(k)%axis(3)
      end if
    end do
  end function component_values

  !> The units of z's columns (the output's column_units); 'unknown' unless the model says.
  pure subroutine column_units(self, units)
    class(generic_model), intent(in) :: self
    character(len=*), intent(out) :: units(:)

    units = 'unknown'
  end subroutine column_units

  !> Number of subsystems.
  pure integer function subsystem_count(self)
    class(generic_model), intent(in) :: self

    subsystem_count = size(self%subsystems)
  end function subsystem_count

  !> Number of temperatures: the subsystems with a thermodynamic variable. A model's subsystems
  !> all have one (a thermal model) or none (a mechanical one, e.g. elastic springs: potentials
  !> of mechanical invariants alone, S = 0, no temperatures, no entropy).
  pure integer function temperature_count(self)
    class(generic_model), intent(in) :: self

    temperature_count = count(self%subsystems%tau_column > 0)
  end function temperature_count

  !> The rounding scale of the mechanical energy at z: the sum of the absolute values of the terms
  !> it is summed from (src/structure/step_balances). This default is |T + V_g|; a model whose
  !> terms can cancel (kinetic against gravity) overrides it.
  pure real(real64) function mechanical_energy_scale(self, z)
    class(generic_model), intent(in) :: self
    real(real64), intent(in) :: z(:)

    mechanical_energy_scale = abs(self%mechanical_energy(z))
  end function mechanical_energy_scale

  !> The rounding scale of the momenta at z: the sum of the absolute values of the terms each
  !> momentum is summed from, the largest over the momenta (src/structure/step_balances). This
  !> default is the largest |momentum|; a model whose terms can cancel overrides it.
  pure real(real64) function momentum_scale(self, z)
    class(generic_model), intent(in) :: self
    real(real64), intent(in) :: z(:)

    momentum_scale = 0.0_real64
    if (self%momentum_count() > 0) momentum_scale = maxval(abs(self%momenta(z)))
  end function momentum_scale

  !> (T + V_g)(z_b) - (T + V_g)(z_a). This default subtracts two values; models override it with
  !> a form free of cancellation (kinetic energy is quadratic, gravity linear).
  pure function mechanical_energy_difference(self, z_a, z_b) result(delta)
    class(generic_model), intent(in) :: self
    real(real64), intent(in) :: z_a(:), z_b(:)
    real(real64) :: delta

    delta = self%mechanical_energy(z_b) - self%mechanical_energy(z_a)
  end function mechanical_energy_difference

  !> The temperatures Theta_a = d_tau U_a / d_tau S_a that partials give (eq. (2)): the discrete
  !> temperatures for discrete-gradient partials.
  pure function partials_temperatures(self, partials) result(theta)
    class(generic_model), intent(in) :: self
    real(real64), intent(in) :: partials(:, :, :)
    real(real64) :: theta(self%temperature_count())
    integer :: a, n

    do a = 1, size(theta)
      n = self%subsystems(a)%invariant_count
      theta(a) = partials(n, potential_u, a)/partials(n, potential_s, a)
    end do
  end function partials_temperatures

  !> The model's own figures of each step (none by default; the spring chain's production
  !> minima), which the run's rows hold after the integrator's.
  function step_figure_list(self) result(figures)
    class(generic_model), intent(in) :: self
    type(model_step_figure), allocatable :: figures(:)

    allocate (figures(0))
  end function step_figure_list

  !> The values of step_figure_list for the step from `old` to `new` (states) of the integrator
  !> `scheme` with discrete gradient `gradient` and `metric` (the chain's discrete temperatures
  !> follow the scheme's rule); stat /= failure_none where they cannot be taken.
  subroutine step_figures(self, scheme, gradient, metric, old, new, values, stat)
    class(generic_model), intent(in) :: self
    character(len=*), intent(in) :: scheme
    integer, intent(in) :: gradient, metric
    real(real64), intent(in) :: old(:), new(:)
    real(real64), allocatable, intent(out) :: values(:)
    integer, intent(out) :: stat

    allocate (values(0))
    stat = failure_none
  end subroutine step_figures

  !> A written-out field's df/dpartials gains the chain through each subsystem's temperature
  !> Theta_a = dU_a/dtau / dS_a/dtau (eq. (2)): df_dtheta(:, a) = df/dTheta_a at fixed partials,
  !> tau_slots(a) the slot of tau_a among subsystem a's invariants.
  pure subroutine add_temperature_chain(partials, tau_slots, df_dtheta, df_dpartials)
    real(real64), intent(in) :: partials(:, :, :), df_dtheta(:, :)
    integer, intent(in) :: tau_slots(:)
    real(real64), intent(inout) :: df_dpartials(:, :, :, :)
    integer :: a

    do a = 1, size(tau_slots)
      associate (t => tau_slots(a), s_tau => partials(tau_slots(a), potential_s, a))
        df_dpartials(:, t, potential_u, a) = df_dpartials(:, t, potential_u, a) + df_dtheta(:, a)/s_tau
        df_dpartials(:, t, potential_s, a) = df_dpartials(:, t, potential_s, a) &
          - df_dtheta(:, a)*(partials(t, potential_u, a)/s_tau)/s_tau
      end associate
    end do
  end subroutine add_temperature_chain

end module model_interface
