# FindSuiteSparse: SuiteSparse 5.x as packaged by Debian (libsuitesparse-dev),
# which ships no CMake package. Components: UMFPACK CHOLMOD KLU (and their
# dependencies AMD, COLAMD, CAMD, CCOLAMD, BTF, SuiteSparse_config).
# Defines imported targets SuiteSparse::<Component> and SuiteSparse_FOUND.

find_path(SuiteSparse_INCLUDE_DIR NAMES umfpack.h cholmod.h klu.h
  PATH_SUFFIXES suitesparse)

set(_ss_all config AMD COLAMD CAMD CCOLAMD BTF CHOLMOD UMFPACK KLU)
set(_ss_lib_config suitesparseconfig)
set(_ss_lib_AMD amd)
set(_ss_lib_COLAMD colamd)
set(_ss_lib_CAMD camd)
set(_ss_lib_CCOLAMD ccolamd)
set(_ss_lib_BTF btf)
set(_ss_lib_CHOLMOD cholmod)
set(_ss_lib_UMFPACK umfpack)
set(_ss_lib_KLU klu)
set(_ss_deps_AMD config)
set(_ss_deps_COLAMD config)
set(_ss_deps_CAMD config)
set(_ss_deps_CCOLAMD config)
set(_ss_deps_BTF "")
set(_ss_deps_CHOLMOD AMD COLAMD CAMD CCOLAMD config)
set(_ss_deps_UMFPACK CHOLMOD AMD config)
set(_ss_deps_KLU AMD COLAMD BTF config)

foreach(_c IN LISTS _ss_all)
  find_library(SuiteSparse_${_c}_LIBRARY NAMES ${_ss_lib_${_c}})
  mark_as_advanced(SuiteSparse_${_c}_LIBRARY)
  if(SuiteSparse_${_c}_LIBRARY AND SuiteSparse_INCLUDE_DIR)
    set(SuiteSparse_${_c}_FOUND TRUE)
  endif()
endforeach()

find_package(BLAS QUIET)
find_package(LAPACK QUIET)

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(SuiteSparse
  REQUIRED_VARS SuiteSparse_INCLUDE_DIR SuiteSparse_config_LIBRARY
  HANDLE_COMPONENTS)
mark_as_advanced(SuiteSparse_INCLUDE_DIR)

if(SuiteSparse_FOUND)
  foreach(_c IN LISTS _ss_all)
    if(SuiteSparse_${_c}_FOUND AND NOT TARGET SuiteSparse::${_c})
      add_library(SuiteSparse::${_c} UNKNOWN IMPORTED)
      set_target_properties(SuiteSparse::${_c} PROPERTIES
        IMPORTED_LOCATION "${SuiteSparse_${_c}_LIBRARY}"
        INTERFACE_INCLUDE_DIRECTORIES "${SuiteSparse_INCLUDE_DIR}")
    endif()
  endforeach()
  foreach(_c IN LISTS _ss_all)
    if(TARGET SuiteSparse::${_c})
      foreach(_d IN LISTS _ss_deps_${_c})
        if(TARGET SuiteSparse::${_d})
          set_property(TARGET SuiteSparse::${_c} APPEND PROPERTY
            INTERFACE_LINK_LIBRARIES SuiteSparse::${_d})
        endif()
      endforeach()
    endif()
  endforeach()
  foreach(_c CHOLMOD UMFPACK)
    if(TARGET SuiteSparse::${_c})
      if(LAPACK_FOUND)
        set_property(TARGET SuiteSparse::${_c} APPEND PROPERTY
          INTERFACE_LINK_LIBRARIES ${LAPACK_LIBRARIES})
      endif()
      if(BLAS_FOUND)
        set_property(TARGET SuiteSparse::${_c} APPEND PROPERTY
          INTERFACE_LINK_LIBRARIES ${BLAS_LIBRARIES})
      endif()
    endif()
  endforeach()
endif()
