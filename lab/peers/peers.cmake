# Adapters for the peer libraries. Each is compiled only when its library is
# found; the library target never depends on them, only the lab does.
set(BROADPHASE_PEERS_FOUND "")

find_package(PkgConfig QUIET)
if(PkgConfig_FOUND)
  pkg_check_modules(BROADPHASE_BULLET QUIET IMPORTED_TARGET bullet)
  pkg_check_modules(BROADPHASE_ODE QUIET IMPORTED_TARGET ode)
endif()
find_package(fcl QUIET)
find_package(CGAL QUIET)

# broadphase_add_peer(NAME SOURCE TARGET...): builds one adapter into the
# lab (broadphase_lab_program). Each adapter is an object library of its own so that its
# library's compile flags (CGAL adds -frounding-math) stay on its own file.
function(broadphase_add_peer name source)
  add_library(broadphase_peer_${name} OBJECT ${CMAKE_CURRENT_LIST_DIR}/${source})
  target_link_libraries(broadphase_peer_${name} PRIVATE broadphase broadphase_warnings ${ARGN})
  target_link_libraries(broadphase_lab_program PRIVATE broadphase_peer_${name})
  string(TOUPPER ${name} upper)
  set_property(SOURCE ${CMAKE_CURRENT_LIST_DIR}/register.cpp APPEND PROPERTY
               COMPILE_DEFINITIONS BROADPHASE_HAVE_${upper})
  set(BROADPHASE_PEERS_FOUND "${BROADPHASE_PEERS_FOUND} ${name}" PARENT_SCOPE)
endfunction()

if(BROADPHASE_BULLET_FOUND)
  broadphase_add_peer(bullet bullet.cpp PkgConfig::BROADPHASE_BULLET)
endif()
if(fcl_FOUND)
  broadphase_add_peer(fcl fcl.cpp fcl)
endif()
if(BROADPHASE_ODE_FOUND)
  broadphase_add_peer(ode ode.cpp PkgConfig::BROADPHASE_ODE)
endif()
if(CGAL_FOUND)
  broadphase_add_peer(cgal cgal.cpp CGAL::CGAL)
endif()
message(STATUS "broadphase: peer adapters:${BROADPHASE_PEERS_FOUND}")

# peers_check: every built adapter against the naive oracle (random
# operations, validate() after each), run by tests/peers_test.sh.
if(BROADPHASE_BUILD_TESTS)
  add_executable(peers_check ${CMAKE_CURRENT_LIST_DIR}/check.cpp)
  target_link_libraries(peers_check PRIVATE broadphase_lab_program broadphase_testing broadphase_warnings)
endif()
