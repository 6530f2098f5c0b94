!> retry_strategies without PETSc: a scripted root finder on a problem whose roots are known
!> shows the order of the strategies (predictor refined by the finder, old state, continuation,
!> then all again with the fallback), that only a physical root ends the search, that
!> continuation solves rising s and accepts only s = 1, and what the search reports.
program test_retry_strategies
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use unit_testing, only: unit_test, run_unit_tests
  use retry_strategies, only: root_search, find_root, strategy_predictor, strategy_old_state, &
                              strategy_continuation, strategies_per_round, first_continuation_fraction, &
                              newton_converged, rounding_factor
  use scripted_solver, only: line_problem, scripted_finder
  implicit none (type, external)

  call run_unit_tests('test_retry_strategies', [ &
    unit_test('predictor_first', predictor_first), &
    unit_test('old_state_second', old_state_second), &
    unit_test('continuation_third', continuation_third), &
    unit_test('fallback_round', fallback_round), &
    unit_test('unphysical_roots_rejected', unphysical_roots_rejected), &
    unit_test('nothing_found', nothing_found), &
    unit_test('without_continuation', without_continuation), &
    unit_test('convergence_test_scale_aware', convergence_test_scale_aware)])

contains

  !> A predictor within reach: one solve, strategy 1, after the finder refined it once.
  subroutine predictor_first(suite)
    type(test_suite), intent(inout) :: suite
    type(line_problem), target :: problem
    type(scripted_finder) :: finder
    type(root_search) :: search
    real(real64) :: root(1)
    integer :: ierr

    finder%reach = 0.5_real64
    call find_root(finder, problem, [0.0_real64], [0.9_real64], root, search, ierr)
    call suite%check_true('accepted', search%accepted)
    call suite%check_equal_int('strategy', search%strategy, strategy_predictor)
    call suite%check_equal_int('solves', search%solves, 1)
    call suite%check_equal_int('refinements of the predictor', finder%refinements, 1)
    call suite%check_close('root', root, [1.0_real64], atol=1.0e-15_real64)
    call suite%check_close('predictor refined before the solve', finder%starts(1:1), [0.95_real64], atol=1.0e-15_real64)
  end subroutine predictor_first

  !> A predictor out of reach, the old state within: strategy 2, from the old state.
  subroutine old_state_second(suite)
    type(test_suite), intent(inout) :: suite
    type(line_problem), target :: problem
    type(scripted_finder) :: finder
    type(root_search) :: search
    real(real64) :: root(1)
    integer :: ierr

    finder%reach = 1.5_real64
    call find_root(finder, problem, [0.0_real64], [5.0_real64], root, search, ierr)
    call suite%check_equal_int('strategy', search%strategy, strategy_old_state)
    call suite%check_equal_int('solves', search%solves, 2)
    call suite%check_close('second start is the old state', finder%starts(2:2), [0.0_real64])
    call suite%check_true('the failed attempt''s reason is cleared', len(search%reason) == 0, search%reason)
  end subroutine old_state_second

  !> Neither within reach: continuation from the old state with rising s, accepted at s = 1.
  subroutine continuation_third(suite)
    type(test_suite), intent(inout) :: suite
    type(line_problem), target :: problem
    type(scripted_finder) :: finder
    type(root_search) :: search
    real(real64) :: root(1)
    integer :: ierr, i

    problem%target = 4.0_real64
    finder%reach = 1.1_real64   ! s rising by 1/4 moves the root by 1: extrapolated starts are exact
    call find_root(finder, problem, [0.0_real64], [-5.0_real64], root, search, ierr)
    call suite%check_true('accepted', search%accepted)
    call suite%check_equal_int('strategy', search%strategy, strategy_continuation)
    call suite%check_close('first continuation stage at s = 1/4', finder%fractions(3:3), [first_continuation_fraction])
    call suite%check_true('s rises through the stages', all([(finder%fractions(i + 1) > finder%fractions(i), &
                          i = 3, finder%solves - 1)]))
    call suite%check_close('the last solve is at s = 1', finder%fractions(finder%solves:finder%solves), [1.0_real64])
    call suite%check_close('root of the step itself', root, [4.0_real64], atol=1.0e-14_real64)
    call suite%check_close('problem left at s = 1', [problem%s], [1.0_real64])
  end subroutine continuation_third

  !> Nothing converges without the fallback: the second round finds it, strategies 4-6.
  subroutine fallback_round(suite)
    type(test_suite), intent(inout) :: suite
    type(line_problem), target :: problem
    type(scripted_finder) :: finder
    type(root_search) :: search
    real(real64) :: root(1)
    integer :: ierr

    finder%reach = 0.5_real64
    finder%converge_only_with_fallback = .true.
    call find_root(finder, problem, [0.0_real64], [0.9_real64], root, search, ierr)
    call suite%check_true('accepted', search%accepted)
    call suite%check_equal_int('strategy', search%strategy, strategies_per_round + strategy_predictor)
    call suite%check_true('the accepting solve used the fallback', finder%with_fallback(finder%solves))
    call suite%check_true('the fallback is switched off afterwards', .not. finder%fallback)
  end subroutine fallback_round

  !> Converged roots that check_root refuses are counted and never accepted.
  subroutine unphysical_roots_rejected(suite)
    type(test_suite), intent(inout) :: suite
    type(line_problem), target :: problem
    type(scripted_finder) :: finder
    type(root_search) :: search
    real(real64) :: root(1)
    integer :: ierr

    problem%limit = 2.0_real64
    finder%lands_at = 3.0_real64      ! every solve converges to an unphysical point
    call find_root(finder, problem, [0.0_real64], [0.9_real64], root, search, ierr)
    call suite%check_true('not accepted', .not. search%accepted)
    call suite%check_equal_int('every converged solve was rejected', search%rejected_roots, search%solves)
    call suite%check_true('the rejection is reported', index(search%last_rejection, 'above the limit') > 0, &
                          search%last_rejection)
    call suite%check_true('the failure names every strategy', index(search%reason, 'continuation') > 0, search%reason)
  end subroutine unphysical_roots_rejected

  !> Out of reach of everything: both rounds fail, with a reason.
  subroutine nothing_found(suite)
    type(test_suite), intent(inout) :: suite
    type(line_problem), target :: problem
    type(scripted_finder) :: finder
    type(root_search) :: search
    real(real64) :: root(1)
    integer :: ierr

    finder%reach = 0.0_real64
    call find_root(finder, problem, [0.0_real64], [0.9_real64], root, search, ierr)
    call suite%check_true('not accepted', .not. search%accepted)
    call suite%check_true('both rounds ran', any(finder%with_fallback(1:finder%solves)) .and. &
                          .not. finder%with_fallback(1))
    call suite%check_true('reason given', index(search%reason, 'no root') == 1, search%reason)
  end subroutine nothing_found

  !> Without continuation (the substeps of a halved step): predictor and old state only.
  subroutine without_continuation(suite)
    type(test_suite), intent(inout) :: suite
    type(line_problem), target :: problem
    type(scripted_finder) :: finder
    type(root_search) :: search
    real(real64) :: root(1)
    integer :: ierr

    finder%reach = 0.1_real64
    call find_root(finder, problem, [0.0_real64], [0.5_real64], root, search, ierr, continue_in_s=.false.)
    call suite%check_true('not accepted', .not. search%accepted)
    call suite%check_equal_int('two solves per round, two rounds', search%solves, 4)
    call suite%check_true('the reason names the strategies tried', &
                          index(search%reason, 'no root from the predictor or from the old state') == 1, search%reason)
  end subroutine without_continuation

  !> Newton's test: the tolerance on residual and update, or both at the rounding of the problem's
  !> scales (never with the default zero scales, never at iteration 0, never by the iterate's size).
  subroutine convergence_test_scale_aware(suite)
    type(test_suite), intent(inout) :: suite
    real(real64), parameter :: tol = 1.0e-8_real64, scale = 500.0_real64, residual_scale = 500.0_real64/1.0e-6_real64
    real(real64) :: floor, residual_floor

    floor = rounding_factor*epsilon(1.0_real64)*scale
    residual_floor = rounding_factor*epsilon(1.0_real64)*residual_scale
    call suite%check_true('residual and update below the tolerance', &
                          newton_converged(3, 0.5*tol, 0.5*tol, scale, tol, 0.0_real64, 0.0_real64, 0.0_real64))
    call suite%check_true('the update above the tolerance is not enough', &
                          .not. newton_converged(3, 0.5*tol, 2*tol, scale, tol, 0.0_real64, 0.0_real64, 0.0_real64))
    call suite%check_true('an initial guess below the tolerance', &
                          newton_converged(0, 0.5*tol, huge(1.0_real64), scale, tol, 0.0_real64, 0.0_real64, 0.0_real64))
    call suite%check_true('at the rounding floor above a tolerance it cannot reach', &
                          newton_converged(3, 0.5*residual_floor, 0.5*floor, scale, 1.0e-20_real64, 0.0_real64, scale, &
                                           residual_scale) .and. residual_floor > tol)
    call suite%check_true('an update above its rounding is not at the floor', &
                          .not. newton_converged(3, 0.5*residual_floor, 2*floor, scale, 1.0e-20_real64, 0.0_real64, &
                                                 scale, residual_scale))
    call suite%check_true('a residual above its rounding is not at the floor', &
                          .not. newton_converged(3, 2*residual_floor, 0.5*floor, scale, 1.0e-20_real64, 0.0_real64, &
                                                 scale, residual_scale))
    call suite%check_true('a run-away iterate does not scale the floor', &
                          .not. newton_converged(3, 1.0e20_real64, 1.0e3_real64, 1.0e25_real64, 1.0e-20_real64, &
                                                 0.0_real64, scale, residual_scale))
    call suite%check_true('no floor without scales', .not. newton_converged(3, 1.0e-10_real64, 1.0e-30_real64, scale, &
                                                                            1.0e-20_real64, 0.0_real64, 0.0_real64, &
                                                                            0.0_real64))
    call suite%check_true('no floor at iteration 0', &
                          .not. newton_converged(0, 0.5*residual_floor, 0.5*floor, scale, 1.0e-20_real64, 0.0_real64, &
                                                 scale, residual_scale))
  end subroutine convergence_test_scale_aware

end program test_retry_strategies
