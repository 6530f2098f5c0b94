!> Test helper of tests/e2e/test_chain_ts.py (built as build/tests/chain_field_probe):
!>   [mpirun -n P] chain_field_probe FILE.nml PREFIX
!> builds FILE.nml's spring chain (&integrator scheme a PETSc TS integrator) and its initial state
!> z0, and writes what the split path offers PETSc TS (src/model/spring_chain/spring_chain_dmda's
!> field_at and jacobian_at on a DMDA over the P ranks) beside the dense model's continuous field:
!>  - PREFIX.field.<rank>: "k row value" lines, the rank's rows (1-based) of the sparse field at
!>    state k: k = 0 is z0, k = 2j - 1 and 2j are z0 + h_j e_j and z0 - h_j e_j (j = 1..n, the
!>    model's unknowns), h_j = 1e-6 max(1, |z0_j|);
!>  - PREFIX.jacobian.<rank>: "row column value" lines, the rank's rows of the sparse df/dz at z0
!>    (every column of the DMDA's unknowns, zeros too);
!>  - PREFIX.dense (rank 0): n lines "h_j f_j" with the dense model's continuous_field f(z0), and
!>    PREFIX.dense_jacobian: its df/dz at z0, n lines of n values.
!> The DMDA of a 'fixed-fixed' chain has unused slots beyond the n unknowns (rows n + 1 ..).
!> Exit status 0; 1 on any failure (printed).
program chain_field_probe
#include <petsc/finclude/petscsys.h>
#include <petsc/finclude/petscmat.h>
  use petscsys
  use petscmat
  use, intrinsic :: iso_fortran_env, only: real64, error_unit
  use run_config, only: run_configuration, read_run_config
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use failures, only: failure_type
  use distributed_model, only: distributed_settings
  use spring_chain_step, only: chain_step_problem
  use spring_chain_dmda, only: distributed_chain
  use spring_chain_sparse_run, only: chain_problem_of
  use vector_arrays, only: borrow_read, give_back_read
  implicit none

  type(run_configuration) :: config
  type(distributed_settings) :: settings
  type(chain_step_problem) :: problem
  type(distributed_chain) :: chain
  type(failure_type) :: failure
  class(generic_model), allocatable :: model
  type(constraint_slot), allocatable :: constraints(:)
  real(real64), allocatable :: z0(:), z(:), h(:), dense_f(:), dense_jacobian(:, :), row_values(:)
  real(real64), pointer :: values(:)
  character(len=4096) :: input, prefix
  character(len=16) :: rank_text
  PetscErrorCode :: ierr
  PetscMPIInt :: rank
  PetscInt :: one, total, columns(1000), row_index(1)
  integer :: n, j, k, r, unit, stat, owned

  PetscCallA(PetscInitialize(ierr))
  PetscCallMPIA(MPI_Comm_rank(PETSC_COMM_WORLD, rank, ierr))
  write (rank_text, '(i0)') rank
  call get_command_argument(1, input)
  call get_command_argument(2, prefix)
  call read_run_config(trim(input), config, failure)
  if (.not. failure%failed()) call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, failure)
  if (.not. failure%failed()) then
    settings%input_file = config%input_file
    settings%scheme = config%integrator%scheme
    call chain_problem_of(settings, model, problem, failure)
  end if
  if (.not. failure%failed()) call chain%create(problem, PETSC_COMM_WORLD, failure)
  if (failure%failed()) then
    write (error_unit, '(a)') 'chain_field_probe: '//failure%text()
    error stop 1
  end if
  n = size(z0)
  h = 1.0e-6_real64*max(1.0_real64, abs(z0))
  owned = chain%context%last_row - chain%context%first_row + 1
  open (newunit=unit, file=trim(prefix)//'.field.'//trim(rank_text), status='replace', action='write')
  do k = 0, 2*n
    z = z0
    if (k > 0) then
      j = (k + 1)/2
      z(j) = z0(j) + merge(h(j), -h(j), mod(k, 2) == 1)
    end if
    call chain%set_state(z, failure)
    if (failure%failed()) error stop 1
    PetscCallA(chain%field_at(chain%x, chain%r, stat, ierr))
    if (stat /= 0) error stop 1
    PetscCallA(borrow_read(chain%r, owned, values, ierr))
    write (unit, '(i0, 1x, i0, 1x, es25.17e3)') (k, chain%context%first_row + r - 1, values(r), r=1, owned)
    PetscCallA(give_back_read(chain%r, values, ierr))
  end do
  close (unit)
  call chain%set_state(z0, failure)
  PetscCallA(chain%jacobian_at(chain%x, chain%jacobian, stat, ierr))
  if (stat /= 0) error stop 1
  total = chain%context%total
  one = 1
  columns(1:total) = [(r - 1, r=1, int(total))]
  allocate (row_values(total))
  open (newunit=unit, file=trim(prefix)//'.jacobian.'//trim(rank_text), status='replace', action='write')
  do r = chain%context%first_row, chain%context%last_row
    row_index(1) = r - 1
    PetscCallA(MatGetValues(chain%jacobian, one, row_index, total, columns, row_values, ierr))
    write (unit, '(i0, 1x, i0, 1x, es25.17e3)') (r, k, row_values(k), k=1, int(total))
  end do
  close (unit)
  if (rank == 0) then
    allocate (dense_f(n), dense_jacobian(n, n))
    call model%continuous_field(z0, dense_f, stat, dense_jacobian)
    if (stat /= 0) error stop 1
    open (newunit=unit, file=trim(prefix)//'.dense', status='replace', action='write')
    write (unit, '(es25.17e3, 1x, es25.17e3)') (h(j), dense_f(j), j=1, n)
    close (unit)
    open (newunit=unit, file=trim(prefix)//'.dense_jacobian', status='replace', action='write')
    do r = 1, n
      write (unit, '(*(es25.17e3, 1x))') dense_jacobian(r, :)
    end do
    close (unit)
  end if
  call chain%destroy(failure)
  PetscCallA(PetscFinalize(ierr))
end program chain_field_probe
