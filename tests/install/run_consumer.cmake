# cmake -P run_consumer.cmake with -DBUILD_DIR -DPREFIX -DCONSUMER_SOURCE -DCONSUMER_BUILD
# -DGENERATOR -DCXX_COMPILER -DBUILD_TYPE: installs BUILD_DIR into PREFIX (emptied first), then
# configures, builds and runs the consumer project against PREFIX. Fails on the first step that
# fails, naming it.
foreach(var BUILD_DIR PREFIX CONSUMER_SOURCE CONSUMER_BUILD GENERATOR CXX_COMPILER BUILD_TYPE)
  if(NOT ${var})
    message(FATAL_ERROR "run_consumer.cmake needs -D${var}=...")
  endif()
endforeach()

function(run_step name)
  message(STATUS "${name}: ${ARGN}")
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${name} failed (${rc})")
  endif()
endfunction()

file(REMOVE_RECURSE "${PREFIX}" "${CONSUMER_BUILD}")
run_step(install "${CMAKE_COMMAND}" --install "${BUILD_DIR}" --prefix "${PREFIX}")
run_step(configure "${CMAKE_COMMAND}" -S "${CONSUMER_SOURCE}" -B "${CONSUMER_BUILD}"
  -G "${GENERATOR}" "-DCMAKE_CXX_COMPILER=${CXX_COMPILER}" "-DCMAKE_BUILD_TYPE=${BUILD_TYPE}"
  "-DCMAKE_PREFIX_PATH=${PREFIX}" -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF)

# The package must be the one just installed, not another voxfield on the machine.
file(STRINGS "${CONSUMER_BUILD}/CMakeCache.txt" found REGEX "^voxfield_DIR:")
string(REGEX REPLACE "^[^=]*=" "" found "${found}")
cmake_path(IS_PREFIX PREFIX "${found}" NORMALIZE from_prefix)
if(NOT from_prefix)
  message(FATAL_ERROR "the consumer found voxfield in '${found}', not under ${PREFIX}")
endif()

run_step(build "${CMAKE_COMMAND}" --build "${CONSUMER_BUILD}")
run_step(run "${CONSUMER_BUILD}/voxfield_consumer")

# The installed binary finds bench/plot.py in PREFIX/share/voxfield through its own path, from a
# working directory outside the sources: `--plot` into a missing folder must fail on the folder
# (checked after the script and python), never on a missing plot.py.
execute_process(COMMAND "${PREFIX}/bin/voxfield" bench --suite generate --plot "${CONSUMER_BUILD}/no-such-folder"
  WORKING_DIRECTORY "${CONSUMER_BUILD}" RESULT_VARIABLE rc ERROR_VARIABLE err OUTPUT_QUIET)
if(NOT EXISTS "${PREFIX}/share/voxfield/plot.py")
  message(FATAL_ERROR "plot.py was not installed into ${PREFIX}/share/voxfield")
endif()
if(err MATCHES "needs plot.py" OR NOT rc EQUAL 2)
  message(FATAL_ERROR "the installed voxfield did not find its plot.py (exit ${rc}): ${err}")
endif()
