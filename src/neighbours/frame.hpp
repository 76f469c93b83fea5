/// \file frame.hpp
/// The frame of a neighbour cell (neighbours.cpp), shared by the one-shot
/// lists and the moving list (moving.cpp): private to the library.
#pragma once

#include <array>
#include <broadphase/neighbours.hpp>
#include <string>

namespace broadphase::neighbours_detail {

/// The frame the bins are laid in: the periodic cell vectors, completed by
/// unit vectors orthogonal to them on the axes that are not periodic.
/// Fractional coordinate k of x is dot(x, col_k); a displacement of length r
/// moves it by at most r * |col_k| (`spread[k]`).
struct Frame {
  std::array<Vec3, 3> col{};
  std::array<double, 3> spread{};
};

/// `v` with 17 significant digits, for messages.
std::string number(double v);

/// The frame of `cell`; throws InvalidNeighbourInput for vectors that are
/// not finite, zero or linearly dependent on the periodic axes.
Frame make_frame(const NeighbourCell& cell);

/// Throws InvalidNeighbourInput naming `name` unless `v` is finite and >= 0
/// (a cutoff or a skin).
void check_cutoff(double v, const std::string& name);

}  // namespace broadphase::neighbours_detail
