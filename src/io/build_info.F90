!> The code version baked in at build time: the release number of the file VERSION, with `git
!> describe` in a git checkout (from the Makefile), e.g. '0.9.0 (git cb77f99)'.
module build_info
  implicit none (type, external)
  private
  public :: code_version

#ifndef EME_VERSION
#define EME_VERSION "unknown"
#endif
  character(len=*), parameter :: code_version = EME_VERSION

end module build_info
