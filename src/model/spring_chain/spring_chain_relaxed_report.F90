!> What the relaxed chain split over ranks (spring_chain_relaxed_run) reports besides its states:
!> the relaxed family's per-step figures declared, the dense path's accuracy warnings at the run's
!> end (a run without a tolerance that halved a step, or whose gamma moved far from 1), and its
!> solver (the implicit stages' SNES, none for explicit stages). A submodule because it
!> reads the run's record.
submodule (spring_chain_relaxed_run) spring_chain_relaxed_report
  implicit none

contains

  !> True: each step's outcome carries the relaxed family's per-step figures (gamma, rejected and
  !> halved attempts, gamma e_S, attempts outside the gamma band), as the dense path declares them.
  pure logical module function integrator_diagnostics(self)
    class(relaxed_chain_run), intent(in) :: self

    integrator_diagnostics = .true.
  end function integrator_diagnostics

  !> The dense path's warnings (src/integrator/relaxed_stepper's accuracy_warnings): a run
  !> without a tolerance that halved a step, or whose gamma moved more than
  !> gamma_warning_deviation from 1; '' otherwise.
  module function accuracy_warnings(self) result(text)
    class(relaxed_chain_run), intent(in) :: self
    character(len=:), allocatable :: text
    logical :: uncontrolled

    text = ''
    uncontrolled = .not. self%gamma_band < huge(1.0_real64)
    if (uncontrolled .and. self%run_rejections > 0) &
      text = integer_text(self%run_rejections)//' trial steps rejected ('//integer_text(self%run_halvings)//' halved)'
    if (self%max_gamma_deviation > gamma_warning_deviation) then
      if (len(text) > 0) text = text//' and '
      text = text//'|gamma - 1| up to '//fixed_text(self%max_gamma_deviation, 3)//' (over '// &
             fixed_text(gamma_warning_deviation, 1)//')'
    end if
    if (len(text) == 0) return
    if (.not. uncontrolled) then
      text = text//': the steps of '//trim(self%settings%scheme)//' at this tolerance are long for its accuracy (E, '// &
             'the momenta and dS >= 0 hold all the same); a smaller &integrator tolerance is the remedy (docs/integrators.md)'
    else
      text = text//': dt = '//reals_text([self%settings%dt])//' s is too long for '//trim(self%settings%scheme)// &
             '''s accuracy, which nothing controlled (E, the momenta and dS >= 0 hold all the same); '// &
             '&integrator tolerance is the remedy (docs/integrators.md)'
    end if
  end function accuracy_warnings

  !> The implicit stages' SNES (distributed_system); none for explicit stages.
  module function describe_solver(self) result(report)
    class(relaxed_chain_run), intent(in) :: self
    type(solver_report) :: report

    if (self%tableau%implicit) then
      report = chain_snes_report(self%stage_solver%snes, 'PETSc SNES of the implicit stages on a DMDA split over the '// &
                                 'ranks: Newton, sparse Jacobian, LU (GMRES on block-Jacobi LU on several ranks) unless '// &
                                 'the options choose a KSP', self%settings%newton_tol, 'eps |z|/h, z the state the step '// &
                                 'starts from, h its length')
    else
      report = no_solver('explicit stages of the chain''s field on a DMDA split over the ranks')
    end if
  end function describe_solver

end submodule spring_chain_relaxed_report
