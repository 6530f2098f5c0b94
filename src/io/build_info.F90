!> The code version baked in at build time (git describe, from the Makefile).
module build_info
  implicit none (type, external)
  private
  public :: code_version

#ifndef EME_VERSION
#define EME_VERSION "unknown"
#endif
  character(len=*), parameter :: code_version = EME_VERSION

end module build_info
