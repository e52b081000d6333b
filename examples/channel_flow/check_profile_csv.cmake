# ctest for channel_flow: run the example (n = 0.5, 17 nodes across, no plots)
# with --check TOL, which exits nonzero when max |u_h - u_exact| / max u_exact on
# the x = l/2 profile exceeds TOL (cmake's math() has integers only, so the
# example does the arithmetic); then check that profile.csv exists, has the
# header y,u,u_exact and has data rows.
# Usage: cmake -DEXE=<channel_flow> -DWORK=<dir> [-DTOL=0.02] -P check_profile_csv.cmake
if(NOT DEFINED TOL)
  set(TOL 0.02)
endif()
file(REMOVE ${WORK}/profile.csv)
execute_process(COMMAND ${EXE} --out-dir ${WORK} --no-plots --n 0.5 --ny 17 --check ${TOL}
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "channel_flow --check ${TOL} failed (exit ${rc})")
endif()
if(NOT EXISTS ${WORK}/profile.csv)
  message(FATAL_ERROR "channel_flow wrote no ${WORK}/profile.csv")
endif()
file(STRINGS ${WORK}/profile.csv lines)
list(LENGTH lines count)
list(GET lines 0 header)
if(NOT header STREQUAL "y,u,u_exact")
  message(FATAL_ERROR "unexpected header in profile.csv: ${header}")
endif()
if(count LESS 3)
  message(FATAL_ERROR "profile.csv has ${count} lines, expected a header and the samples")
endif()
if(NOT EXISTS ${WORK}/channel_flow.vtu)
  message(FATAL_ERROR "channel_flow wrote no ${WORK}/channel_flow.vtu")
endif()
