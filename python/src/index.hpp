/// \file index.hpp
/// `IndexCore`, the compiled index behind `broadphase.Index`, with the guard
/// that keeps its queries and mutations apart (`UseCounter`) and the iterator
/// over a snapshot of its pairs (`PairChunks`).
#pragma once

#include <pybind11/pybind11.h>

#include <atomic>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/registry.hpp>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "input.hpp"
#include "output.hpp"

namespace broadphase_python {

namespace py = pybind11;
namespace bp = broadphase;

/// Who is using an index: >0 queries running, -1 a mutation. Queries may
/// overlap each other; a mutation needs the index to itself, and a call that
/// would break that raises RuntimeError instead of racing.
class UseCounter {
 public:
  class Reading {
   public:
    explicit Reading(UseCounter& u) : u_(u) {
      int s = u_.state_.load();
      do {
        if (s < 0)
          throw std::runtime_error(
              "broadphase.Index: a mutation (update, insert, remove) is running on another thread; "
              "queries need it to finish first");
      } while (!u_.state_.compare_exchange_weak(s, s + 1));
    }
    ~Reading() { u_.state_.fetch_sub(1); }
    Reading(const Reading&) = delete;
    Reading& operator=(const Reading&) = delete;

   private:
    UseCounter& u_;
  };
  class Writing {
   public:
    explicit Writing(UseCounter& u) : u_(u) {
      int expected = 0;
      if (!u_.state_.compare_exchange_strong(expected, -1))
        throw std::runtime_error(
            expected < 0 ? "broadphase.Index: another mutation is running on another thread; "
                           "mutations need exclusive use"
                         : "broadphase.Index: queries are running on other threads; mutations "
                           "(update, insert, remove) need exclusive use");
    }
    ~Writing() { u_.state_.store(0); }
    Writing(const Writing&) = delete;
    Writing& operator=(const Writing&) = delete;

   private:
    UseCounter& u_;
  };

 private:
  std::atomic<int> state_{0};
};

/// An iterator over a snapshot of an index's pairs, `chunk` rows at a time.
struct PairChunks {
  std::shared_ptr<const PairVec> pairs;
  std::size_t pos = 0;
  std::size_t chunk = 0;

  IntArray next();
};

/// The index behind `broadphase.Index`. Ids are stable: 0..n-1 at
/// construction, then increasing numbers for inserted objects, never reused.
///
/// Two back ends:
/// - lean (no structure name): a PairTracker over arrays. Borrowing: the
///   caller's arrays, read in place (no copy), kept alive by the index; the
///   objects can move but their number is fixed. Owning: the index's own
///   columns (after insert, remove or update(ids, ...)); removal moves the
///   last object into the hole, so slots and ids differ and are mapped.
///   The pairs are found when the index changes, so queries only read.
/// - a structure of the library by name (the handle API): the structure owns
///   copies of the shapes; the pairs are found at the first query after a
///   change, under a lock, and kept.
class IndexCore {
 public:
  IndexCore(const py::buffer& centers, const py::object& radii, const py::object& half,
            const py::object& kinds, const std::string& structure, unsigned threads, double skin,
            std::size_t spare_bytes, const py::object& groups, const py::object& masks);

  std::size_t size() const { return live_; }
  bool borrowing() const { return structure_ == nullptr && borrowed_.has_value(); }
  std::string structure() const { return spec_.empty() ? "lean" : spec_; }

  /// Every live id, increasing.
  IntArray ids();

  /// All objects moved: new centres (and sizes), one row per live id in
  /// increasing order. A borrowing index borrows the new arrays instead.
  void update_all(const py::buffer& centers, const py::object& radii, const py::object& half);

  /// The caller changed its borrowed arrays in place: all objects, or those in
  /// `ids`, may have moved.
  void update_in_place(const py::object& ids);

  /// Objects `ids` moved to `centers` (and sizes). Turns a borrowing index
  /// into an owning one (one copy of the arrays).
  void update_ids(const py::object& ids, const py::buffer& centers, const py::object& radii,
                  const py::object& half);

  /// Adds objects; returns their new ids. Turns a borrowing index into an
  /// owning one.
  IntArray insert(const py::buffer& centers, const py::object& radii, const py::object& half,
                  const py::object& kinds, const py::object& groups, const py::object& masks);

  /// Objects `ids` (all live ids in increasing order when None) take the
  /// collision filters `groups[k]`, `masks[k]`; the pairs are found again.
  void set_filters(const py::object& ids, const py::buffer& groups, const py::buffer& masks);

  /// Removes objects by id. Turns a borrowing index into an owning one.
  void remove(const py::object& ids);

  /// The pairs (ids, i < j) as an int64 (M, 2) array.
  IntArray pairs(bool sorted);

  std::uint64_t count_pairs();

  PairChunks iter_pairs(std::size_t chunk);

  /// Bipartite: pairs (q, id), q a row of the other set, id an object of the
  /// index, sorted by q then id.
  IntArray query(const py::buffer& centers, const py::object& radii, const py::object& half,
                 const py::object& kinds);

  /// The ids of the objects that overlap the box [lo, hi], increasing.
  IntArray query_box(const std::vector<double>& lo, const std::vector<double>& hi);

  /// Casts rays (rays.hpp): closest hits as (ids, t bits), or every hit as
  /// (offsets, ids, t bits). The lean back end has no structure to walk: it
  /// builds a k-d tree over its objects for the call.
  py::tuple ray_cast(const py::buffer& origins, const py::buffer& directions,
                     const py::object& tmax, const py::object& ray_masks, bool all_hits,
                     unsigned threads);

  /// The world hint of a structure built over `o`: the objects' bounding box.
  static bp::Aabb world_of(const bp::Objects& o);

  std::size_t memory_bytes();

  void validate();

 private:
  static constexpr std::uint32_t kGone = std::numeric_limits<std::uint32_t>::max();

  bool alive(std::uint32_t id) const { return id < next_id_ && slot_of_id_[id] != kGone; }

  std::vector<std::uint32_t> live_ids() const;

  /// Reads an int64 1-D buffer of ids (the Python layer converts) and checks
  /// each names a live object.
  std::vector<std::uint32_t> id_vector(const py::object& ids_obj);

  std::vector<std::uint32_t> slots_of(const py::object& ids);

  /// New centres with sizes: the given ones, or when none are given, the
  /// objects' current sizes (so `update(centers)` moves without resizing).
  ObjectArrays with_current_sizes(const py::buffer& centers, const py::object& radii,
                                  const py::object& half, std::size_t rows);

  /// Moves objects `ids` (row k of `o` for ids[k]).
  void apply_moves(const std::vector<std::uint32_t>& ids, const ObjectArrays& o);

  static std::string kind_mismatch(std::uint32_t id);

  /// Row k of `o` applied to `old`: new centre; new size when given (the
  /// radius of a sphere, the half-extents of a box), else the old size.
  static bp::Shape moved_shape(const bp::Shape& old, const ObjectArrays& o, std::size_t k,
                               bool keep);

  // --- the lean back end -------------------------------------------------

  /// Finds the pairs again after a change (exclusive use is held).
  void refresh_lean(const bp::Changes& changes);

  const bp::Objects& lean_objects() const;

 private:
  /// Copies a borrowing index's objects into its own columns (once).
  void own();

  bp::Shape owned_shape(std::size_t s) const;
  void set_shape_raw(std::size_t s, const bp::Shape& sh, bool count);
  void set_shape(std::size_t s, const bp::Shape& sh) { set_shape_raw(s, sh, false); }
  void push_shape(const bp::Shape& sh);
  void copy_slot(std::size_t from, std::size_t to);
  void pop_slot();
  /// Points the Objects view at the own columns; the kind column is read only
  /// when both kinds are present (one kind: the cheaper all-sphere or
  /// all-box layout).
  void rebind_owned();
  std::size_t owned_bytes() const;

  // --- the structure back end --------------------------------------------

  void set_id_of_index(std::uint32_t index, std::uint32_t id);

  /// The current pair list; the structure back end finds it at the first
  /// query after a change, one thread doing so while the others wait.
  std::shared_ptr<const PairVec> snapshot();

  /// Points the lean objects at the filter columns (none when empty).
  void bind_filters();

  std::string spec_;
  unsigned threads_ = 1;
  UseCounter use_;
  std::mutex mu_;  // guards snap_, dirty_ and the tracker
  std::shared_ptr<const PairVec> snap_ = std::make_shared<PairVec>();
  bool dirty_ = false;
  bool keep_sizes_ = false;

  std::vector<std::uint32_t> id_of_slot_;  // lean: slot -> id
  std::vector<std::uint32_t> slot_of_id_;  // id -> slot (lean) or kGone when removed
  std::uint32_t next_id_ = 0;
  std::atomic<std::size_t> live_{0};  // read by len() without the in-use counter
  bool identity_ = true;              // lean: slot == id for every object

  // lean
  std::unique_ptr<bp::PairTracker> tracker_;
  std::optional<ObjectArrays> borrowed_;
  std::vector<py::object> borrowed_py_;  // radii, half-extents, kinds borrowed (or None)
  std::vector<double> xyz_, r_, half_;
  std::vector<std::uint8_t> kind_;
  // lean: the collision filters by slot (copies, borrowing or owning); empty
  // until an object gets one
  std::vector<std::uint32_t> group_, mask_;
  std::size_t spheres_ = 0, boxes_ = 0;
  bp::Objects owned_objects_;

  // structure
  std::unique_ptr<bp::AnyBroadPhase> structure_;
  std::vector<bp::Handle> handle_of_id_;
  std::vector<std::uint32_t> id_of_index_;
};

}  // namespace broadphase_python
