/// \file fast_grid.hpp
/// Deprecated: `fast-grid` is now `grid-verlet`, class GridVerlet in
/// grid_verlet.hpp. This header forwards to it and keeps the old names.
#pragma once

#include <broadphase/grid_verlet.hpp>

namespace broadphase {

/// Deprecated name of GridVerlet.
using FastGrid [[deprecated("FastGrid is now GridVerlet (grid_verlet.hpp)")]] = GridVerlet;
/// Deprecated name of GridVerletOptions.
using FastGridOptions [[deprecated("FastGridOptions is now GridVerletOptions (grid_verlet.hpp)")]] =
    GridVerletOptions;

}  // namespace broadphase
