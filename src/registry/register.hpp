// Each family of structures registers itself from its own folder, so that
// adding a structure touches only that family's files.
#pragma once

#include <algorithm>
#include <broadphase/registry.hpp>
#include <cstdint>
#include <limits>
#include <memory>

namespace broadphase::detail {

void register_study(Registry& r);  // src/study: naive, octree-paper, hgrid-paper
void register_grids(Registry& r);  // src/grids: the uniform and hierarchical grids
void register_trees(Registry& r);  // src/trees: octrees, k-d tree, sweeps, AABB tree
void register_fast(Registry& r);   // src/fast: the performance-tuned structures

/// Makes S from a Config without options and its options as text, read
/// into S::Options (S::Options::from, defined beside the registration):
/// the typed constructor S(config, options).
template <class S>
std::unique_ptr<AnyBroadPhase> build_structure(const Config& c, const OptionText& text) {
  return std::make_unique<Erased<S>>(c, S::Options::from(text));
}

/// Registers a structure type S (build_structure; `make`, for callers that
/// hold a Config with options, reads them the same way).
template <class S>
void add_structure(Registry& r, std::string name, std::string description) {
  r.add({std::move(name), std::move(description), false,
         [](const Config& c) { return build_structure<S>(without_options(c), c.options); },
         &build_structure<S>});
}

/// A whole number read as text, narrowed to the option's type; a value too
/// large for it saturates, which the options' check() then refuses.
template <class T>
T narrow(std::uint64_t v) {
  return static_cast<T>(
      std::min<std::uint64_t>(v, static_cast<std::uint64_t>(std::numeric_limits<T>::max())));
}

}  // namespace broadphase::detail
