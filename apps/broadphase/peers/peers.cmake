# Adapters for the peer libraries. Each is compiled only when its Debian
# package is installed; the rest of the CLI does not depend on any of them.
target_sources(broadphase_app PRIVATE ${CMAKE_CURRENT_LIST_DIR}/register.cpp)
