# FindMUMPS: sequential MUMPS as packaged by Debian (libmumps-seq-dev), which
# ships no CMake package. Defines the imported target MUMPS::MUMPS (double
# and single precision, with the sequential library's MPI stub and PORD) and MUMPS_FOUND.

find_path(MUMPS_INCLUDE_DIR NAMES dmumps_c.h)
# The sequential build's MPI stub header (mpi.h) lives in its own folder.
find_path(MUMPS_SEQ_INCLUDE_DIR NAMES mpi.h PATH_SUFFIXES mumps_seq NO_DEFAULT_PATH
  PATHS ${MUMPS_INCLUDE_DIR} /usr/include /usr/local/include)
set(_mumps_libs dmumps_seq smumps_seq mumps_common_seq mpiseq_seq pord_seq)
set(MUMPS_LIBRARIES "")
foreach(_l IN LISTS _mumps_libs)
  find_library(MUMPS_${_l}_LIBRARY NAMES ${_l})
  mark_as_advanced(MUMPS_${_l}_LIBRARY)
  list(APPEND MUMPS_LIBRARIES ${MUMPS_${_l}_LIBRARY})
endforeach()
mark_as_advanced(MUMPS_INCLUDE_DIR MUMPS_SEQ_INCLUDE_DIR)

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(MUMPS REQUIRED_VARS MUMPS_INCLUDE_DIR MUMPS_SEQ_INCLUDE_DIR
  MUMPS_dmumps_seq_LIBRARY MUMPS_smumps_seq_LIBRARY MUMPS_mumps_common_seq_LIBRARY MUMPS_mpiseq_seq_LIBRARY MUMPS_pord_seq_LIBRARY)

if(MUMPS_FOUND AND NOT TARGET MUMPS::MUMPS)
  add_library(MUMPS::MUMPS INTERFACE IMPORTED)
  set_target_properties(MUMPS::MUMPS PROPERTIES
    INTERFACE_INCLUDE_DIRECTORIES "${MUMPS_INCLUDE_DIR};${MUMPS_SEQ_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES "${MUMPS_LIBRARIES}")
endif()
