!> Step-size control of relaxed_dp853 (src/integrator/relaxed_stepper): DOP853's error norm
!> (Hairer, Norsett and Wanner) of the embedded orders 5 and 3 against the tolerance, and the
!> controller that accepts or rejects a relaxed step and proposes the next.
!> (A .F90 file, compiled as the PETSc sources are, without -std: the parent's scope, which it
!> inherits, holds the PETSc types of its SNES solver.)
submodule (relaxed_stepper) relaxed_step_control
  use dop853_control, only: error_squares, dop853_error_norm, accepted_step_factor, rejected_step_factor, &
                            max_error_rejections
  implicit none (type, external)

contains

  ! One accepted step of the adaptive method: DOP853's error norm (Hairer, Norsett, Wanner)
  ! against `tolerance`, h_new = h min(6, max(1/3, 0.9 err^(-1/8))), and no growth right after a
  ! rejection, as DOP853 does; a failed or guarded step is halved. The step that reaches t_end
  ! lands on it.
  module procedure adaptive_step
    real(real64) :: h, error_norm
    logical :: landing
    integer :: tries

    ok = .false.
    h = self%h_next
    do tries = 1, max_error_rejections
      landing = self%t + (1.0_real64 + landing_slack)*h >= landing_time(self)
      if (landing) h = landing_time(self) - self%t
      call relaxed_step(self, h, landing, ok, error_norm, failure)
      if (failure%failed()) return
      if (ok .and. error_norm <= 1.0_real64) then
        if (.not. landing) self%h_next = h*accepted_step_factor(error_norm, tries > 1)
        return
      end if
      self%rejections = self%rejections + 1
      if (ok) then
        ! Relaxed, but not accepted by the error test: undo and retry smaller.
        call self%restore()
        h = h*rejected_step_factor(error_norm)
        ok = .false.
      else
        h = 0.5_real64*h
        self%halvings = self%halvings + 1
      end if
      if (h <= 1.0e-14_real64*max(1.0_real64, abs(self%t))) exit
    end do
    self%last_failure = 'the adaptive step shrank below round-off or was rejected ' &
                        //integer_text(max_error_rejections)//' times (last: '//self%last_failure//')'
  end procedure adaptive_step

  ! DOP853's error norm of a step of h (src/solver/dop853_control).
  module procedure step_error_norm
    error_norm = dop853_error_norm(h, error_squares(self%tolerance, matmul(k, self%tableau%e5), &
                                                    matmul(k, self%tableau%e3), self%z, z_new), size(z_new))
  end procedure step_error_norm

end submodule relaxed_step_control
