# ctest: the --nodes/--points/--out mode on a small perturbed cloud; the example's
# --check reads its own output back and verifies partition of unity and linear
# reproduction for every point; here we also check the header line.
file(MAKE_DIRECTORY ${WORK})
set(nodes "x,y\n")
foreach(j RANGE 0 6)
  foreach(i RANGE 0 6)
    # Interior nodes moved by up to 0.4 h (a deterministic pattern); boundary on the square.
    math(EXPR kx "(${i} * 7 + ${j} * 3) % 5")
    math(EXPR ky "(${i} * 2 + ${j} * 5) % 5")
    if(i EQUAL 0 OR i EQUAL 6 OR j EQUAL 0 OR j EQUAL 6)
      string(APPEND nodes "${i}.0,${j}.0\n")
    else()
      string(APPEND nodes "${i}.${kx},${j}.${ky}\n")
    endif()
  endforeach()
endforeach()
file(WRITE ${WORK}/nodes.csv "${nodes}")
file(WRITE ${WORK}/points.csv "x,y\n0.5,0.5\n3.3,2.7\n5.9,5.1\n0.0,3.0\n2.25,0.0\n")
execute_process(COMMAND ${EXE} --nodes ${WORK}/nodes.csv --points ${WORK}/points.csv
                        --gamma 1.6 --out ${WORK}/basis.csv --check
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "basis_functions --check failed (${rc})")
endif()
file(STRINGS ${WORK}/basis.csv lines LIMIT_COUNT 1)
if(NOT lines STREQUAL "point,node,p,dpdx,dpdy")
  message(FATAL_ERROR "unexpected header: ${lines}")
endif()
