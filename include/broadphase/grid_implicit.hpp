/// \file grid_implicit.hpp
/// `grid-implicit`: the grid as the Cartesian product of three per-axis
/// slab arrays. Each slab holds a bit array (std::uint64_t words, one bit
/// per object slot) of the objects whose bounds overlap it; the candidates
/// of a cell are the AND of its three slabs' bit arrays, and the candidates
/// of a whole object are AND(OR of its x slabs, OR of its y slabs, OR of its
/// z slabs), computed a word at a time.
///
/// Each pair once: object a takes only the candidates b > a (slot order),
/// so no cell rule is needed. Exact: slab ranges come from the monotone cell
/// map of grid_common.hpp, so overlapping boxes share a slab on every axis.
///
/// World: slabs cover Config::world, at most 1024 per axis (the cell edge
/// grows until the world fits); objects outside are clamped into the border
/// slabs (exact, slower when many are outside). Memory is 3 x slabs x n
/// bits: it grows with the world's extent divided by the cell edge, which is
/// the design (a few hundred bytes per object at 1024 slabs per axis).
///
/// Rays: each slab also keeps a summary, one bit per word of its bit array
/// that is not zero, so that a cell's objects are found by reading only
/// the words whose summary bits are set on all three axes (a sixty-fourth
/// of the bit arrays, and mostly none of their words).
#pragma once

#include <array>
#include <bit>
#include <broadphase/config_error.hpp>
#include <broadphase/detail/grid_common.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/structure.hpp>
#include <cstdint>
#include <vector>

namespace broadphase {

/// The options of GridImplicit (`grid-implicit:cell=E`).
struct GridImplicitOptions {
  /// Cell edge in world units, in [1e-300, 1e300]; 0 (default): chosen from
  /// the world and the population.
  double cell = 0;
  /// Throws InvalidConfig for a value out of range (detail/structure_base.hpp).
  void check() const;
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static GridImplicitOptions from(const OptionText& text);
};

/// A uniform grid stored as per-axis slab bit arrays.
/// insert, update: O(slabs covered x 1) bit flips (plus, rarely, a re-layout
/// O(n x slabs / 64) when slots outgrow the bit arrays or the cell size is
/// re-chosen). remove: O(slabs covered). query: O(slabs covered x n / 64 +
/// candidates). for_each_pair: O(n x slabs per object x n / 128 +
/// candidates): quadratic in words, fast for small n thanks to 64-bit ANDs.
/// Options: `cell=`. Handles stay valid until their object is removed.
/// Const members may run concurrently; mutations need exclusive access.
class GridImplicit : public detail::StoreBase<GridImplicit> {
 public:
  /// Slabs per axis at most.
  static constexpr std::int32_t kMaxSlabs = 1024;

  using Options = GridImplicitOptions;
  /// Reads the deprecated Config::options map into GridImplicitOptions.
  /// Throws InvalidConfig.
  explicit GridImplicit(const Config& c = {})
      : GridImplicit(without_options(c), GridImplicitOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o` (GridImplicitOptions::check).
  GridImplicit(const Config& c, const GridImplicitOptions& o);

  /// Adds an object. Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion m = Motion::dynamic);
  /// Removes an object. Throws InvalidHandle.
  void remove(Handle h);
  /// Moves an object; only axes whose slab range changed are touched.
  /// Throws InvalidHandle, InvalidShape.
  void update(Handle h, const Shape& s);

  /// Visits every object overlapping `q`.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    require_valid(q);
    QueryCost cost;
    const AabbF qb = bounds_f(q);
    const detail::CellRange r = map_.range(qb);
    for (std::size_t w = 0; w < words_; ++w) {
      std::uint64_t c = gather(r, w);
      while (c != 0) {
        const std::uint32_t b = static_cast<std::uint32_t>(w * 64 + std::countr_zero(c));
        c &= c - 1;
        if (!detail::test_query(store_, box_.data(), q, qb, b, cost, visitor)) return cost;
      }
    }
    return cost;
  }

  /// Casts a ray (HasRayCast): a march through the cells the ray passes
  /// (detail/ray_walk.hpp), a cell's objects read through the slabs'
  /// summaries (cell_objects), each object tested once. O(cells passed x
  /// n / 4096 + candidates), and never more than about a scan of every
  /// object. Throws InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const {
    auto box_of = [&](std::uint32_t b) -> const AabbF& { return box_[b]; };
    const std::array<std::uint32_t, 0> loose{};  // every object is in the slabs
    return detail::ray_grid_cast(
        store_, r, visitor, loose, box_of, [&](auto& cast, detail::RaySlots& tested) {
          // A cell reads 3 x summary words; a scan tests each object (about
          // as much as reading 16 words).
          const double budget = 2.0 * static_cast<double>(store_.size()) * 16 /
                                    (3 * static_cast<double>(summary_words_) + 16) +
                                64;
          detail::ray_level_cast(
              cast, tested, detail::ray_level(map_), budget, &occupied_,
              [&](double x, int a) { return map_.coord(x, a); },
              [&](const detail::CellKey& k, auto&& f) { return cell_objects(k, f); },
              [&](auto&& f) {
                for (std::uint32_t b = 0; b < store_.slot_count(); ++b)
                  if (store_.slots().alive(b) && !f(b)) return false;
                return true;
              },
              box_of);
        });
  }

  /// The pair walk behind for_each_pair (StoreBase, which attaches the
  /// filters): every overlapping pair once (candidates b > a of each a).
  template <class V>
  QueryCost walk_pairs(V& visitor) const {
    QueryCost cost;
    const std::uint32_t slots = store_.slot_count();
    for (std::uint32_t a = 0; a < slots; ++a) {
      if (!store_.slots().alive(a)) continue;
      const detail::CellRange& r = range_[a];
      for (std::size_t w = a / 64; w < words_; ++w) {
        std::uint64_t c = gather(r, w);
        if (w == a / 64) c &= ~std::uint64_t{0} << (a % 64) << 1;
        while (c != 0) {
          const std::uint32_t b = static_cast<std::uint32_t>(w * 64 + std::countr_zero(c));
          c &= c - 1;
          if (!detail::test_pair(store_, box_.data(), a, b, cost, visitor)) return cost;
        }
      }
    }
    return cost;
  }

  /// Bytes held: store, bounds, ranges, the three slab bit arrays and
  /// their summaries.
  std::size_t memory_bytes() const;
  /// The cell (slab) edge in use.
  double cell_size() const { return map_.cell(); }

  /// Checks bounds, ranges, every bit of every slab and of the summaries,
  /// and the occupied box.
  void validate() const;
  /// Reports every cell (level 0) that the bounds of some object touch, with
  /// their number. O(cells touched log cells).
  void visit_cells(CellVisitor visitor) const;

 private:
  // The candidates of range r in word w: AND over axes of the OR of slabs.
  std::uint64_t gather(const detail::CellRange& r, std::size_t w) const {
    std::uint64_t c = ~std::uint64_t{0};
    for (int a = 0; a < 3 && c != 0; ++a) {
      std::uint64_t any = 0;
      const std::uint64_t* p = bits_[a].data() + static_cast<std::size_t>(r.lo[a]) * words_ + w;
      for (std::int32_t s = r.lo[a]; s <= r.hi[a]; ++s, p += words_) any |= *p;
      c &= any;
    }
    return c;
  }
  // Calls f(b) for the objects of cell `k` (the AND of its three slabs),
  // reading only the words that all three slabs' summaries mark non-zero;
  // false as soon as f is.
  template <class F>
  bool cell_objects(const detail::CellKey& k, F&& f) const {
    const std::uint64_t* sum[3];
    const std::uint64_t* bits[3];
    for (int a = 0; a < 3; ++a) {
      const auto s = static_cast<std::size_t>(k.c[a]);
      sum[a] = summary_[a].data() + s * summary_words_;
      bits[a] = bits_[a].data() + s * words_;
    }
    for (std::size_t v = 0; v < summary_words_; ++v) {
      std::uint64_t m = sum[0][v] & sum[1][v] & sum[2][v];
      while (m != 0) {
        const std::size_t w = v * 64 + static_cast<std::size_t>(std::countr_zero(m));
        m &= m - 1;
        std::uint64_t c = bits[0][w] & bits[1][w] & bits[2][w];
        while (c != 0) {
          const auto b = static_cast<std::uint32_t>(w * 64 + std::countr_zero(c));
          c &= c - 1;
          if (!f(b)) return false;
        }
      }
    }
    return true;
  }
  void set_bits(std::uint32_t i, int axis, std::int32_t lo, std::int32_t hi, bool on);
  void layout(double cell, std::size_t words);

  std::vector<AabbF> box_;
  std::vector<detail::CellRange> range_;
  std::vector<std::uint64_t> bits_[3];  // per axis: slab-major, words_ words per slab
  std::size_t words_ = 0;
  std::vector<std::uint64_t> summary_[3];  // per axis: slab-major, a bit per non-zero word
  std::size_t summary_words_ = 0;          // per slab: ceil(words_ / 64)
  detail::OccupiedBox occupied_;           // holds every object's bounds (rays)
  std::int32_t slabs_[3] = {1, 1, 1};
  Aabb world_;
  detail::CellMap map_;
  detail::RegridTrigger trigger_;
};

}  // namespace broadphase
