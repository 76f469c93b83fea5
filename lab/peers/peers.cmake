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
# Intel Embree 3 (libembree-dev): a ray peer only (peers/ray_peers.hpp).
find_package(embree 3 QUIET)

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
if(embree_FOUND)
  broadphase_add_peer(embree embree.cpp embree)
elseif(BROADPHASE_BULLET_FOUND AND fcl_FOUND AND BROADPHASE_ODE_FOUND AND CGAL_FOUND)
  # Every other peer of tools/deps.sh is here, so deps.sh ran, and it
  # installs Embree too: a missing Embree means an old deps.sh run, not a
  # choice; the lab's ray section would silently lose its reference.
  message(FATAL_ERROR "broadphase: the peers of tools/deps.sh are installed but Intel Embree 3 "
                      "(libembree-dev) is not: run tools/deps.sh again, or configure with "
                      "-DBROADPHASE_WITH_PEERS=OFF to build no peer at all")
endif()
message(STATUS "broadphase: peer adapters:${BROADPHASE_PEERS_FOUND}")

# peers_check: every built adapter against the naive oracle (random
# operations, validate() after each), run by tests/peers_test.sh.
if(BROADPHASE_BUILD_TESTS)
  add_executable(peers_check ${CMAKE_CURRENT_LIST_DIR}/check.cpp)
  target_link_libraries(peers_check PRIVATE broadphase_lab_program broadphase_testing broadphase_warnings)
endif()
