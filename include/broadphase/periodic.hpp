/// \file periodic.hpp
/// Periodic worlds over any structure: an adapter that gives a structure of
/// the registry (or any AnyBroadPhase) images of the objects near the faces
/// of an orthorhombic cell and reports each periodic pair (a, b, S) once,
/// exactly as docs/scene-format.md ("Periodic worlds") evaluates it.
///
/// The cell is [0, L_x] x [0, L_y] x [0, L_z], each axis periodic or not
/// (a slab: x and y; a tube: x; bulk: all three). A pair (a, b, S) means
/// that object a, as it lies, overlaps object b moved by S·L, where S has
/// components in {-1, 0, 1} (0 on the axes that are not periodic) and b's
/// moved centre is computed in double, c_b + S_a·L_a per axis: the
/// contract's triple (i, j, S) with i < j. One a, b may pair under several
/// shifts (near half the cell); each is reported.
///
/// How (docs/periodic.md): besides each object, the wrapped structure holds
/// its images c + T·L for the shifts T allowed by the image rule below. A
/// pair of two copies is kept only when the object that stays in place
/// (the one with the smaller user data, then the smaller slot: a scene's
/// object ids) is its original and the other is the copy shifted by T; it
/// is reported with S = T. The structure evaluated exactly that pair on
/// exactly the double coordinates the contract names, so its own exact
/// predicate and its conservative culling decide it: no second test, and
/// no pair is found twice (a pair of two copies is visited once).
///
/// The image rule: on a periodic axis a, an object with centre c and
/// half-extent e (its bounding box's, a sphere's radius) has images shifted
/// by +L_a when c - e <= R_a and by -L_a when c + e >= L_a - R_a, and images
/// for every combination of the axes on which it has one, where R_a is the
/// largest half-extent on axis a of any object held so far, plus a margin
/// of 2^-40 (L_a + R_a) for rounding. Sufficient: if a overlaps b moved by
/// +L_a, then (c_b + L_a) - c_a <= e_a + e_b up to rounding and c_a <= L_a,
/// so c_b - e_b <= e_a <= R_a; the same for -L_a with c_a >= 0.
///
/// Rays do not wrap (the contract): `cast_ray` reports originals only.
/// Thread-safety: as the structure it wraps; `find_pairs` and `cast_ray`
/// are const and may run concurrently with each other.
#pragma once

#include <array>
#include <broadphase/geometry.hpp>
#include <broadphase/handle.hpp>
#include <broadphase/ray.hpp>
#include <broadphase/structure.hpp>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace broadphase {

/// A periodic shift S: each component in {-1, 0, 1}.
struct Shift {
  std::int8_t x = 0, y = 0, z = 0;
  constexpr int operator[](int axis) const { return axis == 0 ? x : (axis == 1 ? y : z); }
  constexpr bool is_zero() const { return x == 0 && y == 0 && z == 0; }
  /// The contract's code of the shift: (Sx+1) + 3(Sy+1) + 9(Sz+1), 0 to 26
  /// (13 for no shift).
  constexpr int code() const { return (x + 1) + 3 * (y + 1) + 9 * (z + 1); }
  /// The shift of a code (0 to 26).
  static constexpr Shift of_code(int code) {
    return {static_cast<std::int8_t>(code % 3 - 1), static_cast<std::int8_t>(code / 3 % 3 - 1),
            static_cast<std::int8_t>(code / 9 - 1)};
  }
  friend constexpr bool operator==(const Shift&, const Shift&) = default;
};

/// An orthorhombic cell [0, length_a] per axis, each axis periodic or not.
struct PeriodicCell {
  Vec3 length{1000, 1000, 1000};
  std::array<bool, 3> periodic{true, true, true};
  /// A cube of side `l` periodic on `axes`.
  static PeriodicCell cube(double l, std::array<bool, 3> axes) { return {{l, l, l}, axes}; }
};

/// One periodic pair: `a` as it lies overlaps `b` moved by `shift`·L.
/// `a` is the object of the two with the smaller user data (then the
/// smaller slot), as the contract's i < j.
struct PeriodicPair {
  Handle a, b;
  Shift shift;
};

/// Runs any structure in a periodic cell (see the file's comment). Objects
/// must have, on each periodic axis a, their centre in [0, L_a] and every
/// half-extent below L_a / 2 (InvalidShape otherwise). Handles are stable
/// until the object is removed.
class PeriodicBroadPhase {
 public:
  /// Wraps `inner`, which must be empty and outlive the adapter; the adapter
  /// owns what it holds from then on (insert only through the adapter).
  /// Throws std::invalid_argument for a cell with a length that is not
  /// finite and positive.
  PeriodicBroadPhase(AnyBroadPhase& inner, PeriodicCell cell);

  /// Adds an object and its images. Throws InvalidShape. Amortised O(1)
  /// plus the structure's inserts, except when its half-extent is the
  /// largest so far on a periodic axis: then every object's images are
  /// renewed, O(n).
  Handle insert(const Shape& s, std::uint64_t user, Motion m = Motion::dynamic, Filter f = {});
  /// Removes an object and its images. Throws InvalidHandle.
  void remove(Handle h);
  /// Moves an object: its images follow, appear and disappear. Throws
  /// InvalidHandle, InvalidShape.
  void update(Handle h, const Shape& s);
  /// Moves many objects (one bulk update of the structure for the copies
  /// that stay). All-or-nothing: every move is checked first.
  void update(std::span<const Move> moves);
  /// Changes an object's filter, and its images' (they pair as it does).
  void set_filter(Handle h, Filter f);
  Filter filter(Handle h) const;

  /// Appends every periodic pair once to `out`. O(the structure's pairs
  /// among originals and images).
  QueryCost find_pairs(std::vector<PeriodicPair>& out) const;
  /// Casts a ray against the originals only (rays do not wrap). Throws
  /// InvalidRay.
  QueryCost cast_ray(const Ray& r, FunctionRef<double(Handle, double)> visitor) const;

  /// Grows the image rule's reach to cover objects with half-extents up to
  /// `largest_half` before they are inserted: a scene's objects then cost
  /// no renewal of the images when a larger one arrives. O(n) when it grows.
  void reserve_reach(const Vec3& largest_half);

  std::size_t size() const { return live_; }
  /// How many images the structure holds besides the originals.
  std::size_t image_count() const { return images_; }
  bool contains(Handle h) const;
  Shape shape(Handle h) const;
  std::uint64_t user_data(Handle h) const;
  const PeriodicCell& cell() const { return cell_; }
  /// The structure's bytes and the adapter's own.
  std::size_t memory_bytes() const;
  /// Checks that every object has exactly the images the rule gives it, at
  /// the right coordinates, and the structure's own invariants; throws
  /// std::logic_error naming the first failure.
  void validate() const;

 private:
  struct Image {
    std::uint8_t code;  // Shift::code()
    Handle handle;      // in the structure
  };
  // The shape lives in the structure alone (the original's): a slot is 56
  // bytes, not 112, and a frame's moves touch one cache line of it.
  struct Slot {
    std::uint64_t user = 0;
    Filter filter;
    Motion motion = Motion::dynamic;
    Handle original;            // null when the slot is free
    std::vector<Image> images;  // sorted by code
  };

  std::size_t slot_of(Handle h) const;
  // Inserts a copy into the structure / removes one, keeping key_of_.
  Handle put(const Shape& s, std::uint64_t k, Motion m, Filter f);
  void drop(Handle h);
  void check_shape(const Shape& s) const;
  // Grows max_half_ and the reach to cover half-extents `h`; true when the
  // reach grew (the caller then renews every object's images).
  bool cover(const Vec3& h);
  // The codes of the images the rule gives `s`, ascending.
  void image_codes(const Shape& s, std::vector<std::uint8_t>& out) const;
  Shape moved(const Shape& s, int code) const;
  // Makes slot `k`'s images those of the rule for `shape`, its new shape:
  // new ones inserted, gone ones removed, the others' moves appended to
  // `moves` (applied by the caller in one bulk update).
  void renew_images(std::size_t k, const Shape& shape, std::vector<Move>& moves);
  void renew_all();
  static std::uint64_t key(std::size_t slot, int code) {
    return (static_cast<std::uint64_t>(slot) << 5) | static_cast<std::uint64_t>(code);
  }

  AnyBroadPhase& inner_;
  PeriodicCell cell_;
  Vec3 reach_{0, 0, 0};     // R_a of the image rule, margin included
  Vec3 max_half_{0, 0, 0};  // largest half-extent held so far per axis
  std::vector<Slot> slots_;
  // key(slot, code) of every copy by its structure handle's index (all ones
  // for an index not in use).
  std::vector<std::uint64_t> key_of_;
  std::vector<std::size_t> free_;
  std::size_t live_ = 0;
  std::size_t images_ = 0;
  std::vector<std::uint8_t> codes_;  // scratch of renew_images
};

}  // namespace broadphase
