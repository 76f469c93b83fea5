/// \file index.cpp
/// The index behind `broadphase.Index`: its lean back end (a PairTracker over
/// borrowed or owned columns, slots mapped to stable ids) and its structure
/// back end (a library structure by name), and the chunked pair iterator.
#include "index.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <utility>

#include "one_shot.hpp"
#include "rays.hpp"

namespace broadphase_python {

IntArray PairChunks::next() {
  if (pos >= pairs->size()) throw py::stop_iteration();
  const std::size_t end = std::min(pairs->size(), pos + chunk);
  IntArray a;
  {
    py::gil_scoped_release nogil;
    a = to_int_array(std::span<const bp::IndexPair>(pairs->data() + pos, end - pos));
  }
  pos = end;
  return a;
}

IndexCore::IndexCore(const py::buffer& centers, const py::object& radii, const py::object& half,
                     const py::object& kinds, const std::string& structure, unsigned threads,
                     double skin, std::size_t spare_bytes, const py::object& groups,
                     const py::object& masks)
    : spec_(structure), threads_(threads) {
  ObjectArrays o = object_arrays(centers, radii, half, kinds);
  attach_filters(o, groups, masks);
  const std::size_t n = o.objects.count;
  id_of_slot_.resize(n);
  std::iota(id_of_slot_.begin(), id_of_slot_.end(), 0u);
  slot_of_id_ = id_of_slot_;
  next_id_ = static_cast<std::uint32_t>(n);
  live_ = n;
  if (spec_.empty()) {
    bp::ArrayOptions options = array_options(threads, false, skin);
    options.spare_bytes = spare_bytes;
    tracker_ = std::make_unique<bp::PairTracker>(options);
    group_ = std::move(o.groups);
    mask_ = std::move(o.masks);
    borrowed_ = std::move(o);
    borrowed_py_ = {radii, half, kinds};
    bind_filters();
    refresh_lean(bp::Changes::everything());
    return;
  }
  bp::Config config;
  config.expected_objects = n;
  config.world = world_of(o.objects);
  structure_ = bp::make_structure(spec_, config);
  py::gil_scoped_release nogil;
  handle_of_id_.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const bp::Handle h = structure_->insert(o.objects.shape(i), i);
    if (!o.groups.empty()) structure_->set_filter(h, {o.groups[i], o.masks[i]});
    handle_of_id_.push_back(h);
    set_id_of_index(h.index, static_cast<std::uint32_t>(i));
  }
  dirty_ = true;
}

IntArray IndexCore::ids() {
  UseCounter::Reading r(use_);
  IntArray a;
  for (std::uint32_t id = 0; id < next_id_; ++id)
    if (alive(id)) a.data.push_back(id);
  a.rows = a.data.size();
  return a;
}

void IndexCore::update_all(const py::buffer& centers, const py::object& radii,
                           const py::object& half) {
  UseCounter::Writing w(use_);
  if (borrowing()) {
    const std::size_t count = borrowed_->objects.count;
    // Sizes not given stay those of the arrays borrowed so far.
    const py::object r = radii.is_none() ? borrowed_py_[0] : radii;
    const py::object h = half.is_none() ? borrowed_py_[1] : half;
    ObjectArrays o = object_arrays(centers, r, h, borrowed_py_[2]);
    if (o.objects.count != count)
      throw BadInput("centers: a borrowing index keeps its object count (" + std::to_string(count) +
                     "), got " + std::to_string(o.objects.count) +
                     " rows; insert and remove give an owning index that can change it");
    borrowed_ = std::move(o);
    borrowed_py_ = {r, h, borrowed_py_[2]};
    bind_filters();
    refresh_lean(bp::Changes::everything());
    return;
  }
  ObjectArrays o = with_current_sizes(centers, radii, half, live_);
  std::vector<std::uint32_t> live = live_ids();
  apply_moves(live, o);
}

void IndexCore::update_in_place(const py::object& ids) {
  UseCounter::Writing w(use_);
  if (!borrowing())
    throw std::runtime_error(
        "broadphase.Index.update() without arrays: this index owns its data (no arrays of yours "
        "to re-read); pass the new centres");
  // Re-check what the caller may have written.
  ObjectArrays& o = *borrowed_;
  {
    py::gil_scoped_release nogil;
    check_values(o.centers, "centers", false);
    if (o.radii) check_values(*o.radii, "radii", true);
    if (o.half) check_values(*o.half, "half_extents", true);
    if (o.kinds) check_kinds(*o.kinds, o.objects.count);
  }
  if (ids.is_none()) {
    refresh_lean(bp::Changes::everything());
    return;
  }
  std::vector<std::uint32_t> slots = slots_of(ids);
  refresh_lean(bp::Changes::only(slots));
}

void IndexCore::update_ids(const py::object& ids, const py::buffer& centers,
                           const py::object& radii, const py::object& half) {
  UseCounter::Writing w(use_);
  std::vector<std::uint32_t> id_list = id_vector(ids);
  ObjectArrays o = with_current_sizes(centers, radii, half, id_list.size());
  apply_moves(id_list, o);
}

IntArray IndexCore::insert(const py::buffer& centers, const py::object& radii,
                           const py::object& half, const py::object& kinds,
                           const py::object& groups, const py::object& masks) {
  UseCounter::Writing w(use_);
  ObjectArrays o = object_arrays(centers, radii, half, kinds);
  attach_filters(o, groups, masks);
  const std::size_t n = o.objects.count;
  if (static_cast<std::uint64_t>(next_id_) + n >= std::numeric_limits<std::uint32_t>::max())
    throw BadInput("insert: more ids than 32 bits can name");
  IntArray out;
  out.rows = n;
  out.data.resize(n);
  if (structure_) {
    py::gil_scoped_release nogil;
    for (std::size_t k = 0; k < n; ++k) {
      const std::uint32_t id = next_id_++;
      const bp::Handle h = structure_->insert(o.objects.shape(k), id);
      if (!o.groups.empty()) structure_->set_filter(h, {o.groups[k], o.masks[k]});
      handle_of_id_.push_back(h);
      set_id_of_index(h.index, id);
      slot_of_id_.push_back(0);
      ++live_;
      out.data[k] = id;
    }
    dirty_ = true;
    return out;
  }
  own();
  if (!o.groups.empty() && group_.empty()) {
    group_.assign(id_of_slot_.size(), bp::Filter{}.group);
    mask_.assign(id_of_slot_.size(), bp::Filter{}.mask);
  }
  {
    py::gil_scoped_release nogil;
    for (std::size_t k = 0; k < n; ++k) {
      const std::uint32_t id = next_id_++;
      const std::uint32_t slot = static_cast<std::uint32_t>(id_of_slot_.size());
      if (!group_.empty()) {
        group_.push_back(o.groups.empty() ? bp::Filter{}.group : o.groups[k]);
        mask_.push_back(o.groups.empty() ? bp::Filter{}.mask : o.masks[k]);
      }
      push_shape(o.objects.shape(k));
      identity_ = identity_ && slot == id;
      id_of_slot_.push_back(id);
      slot_of_id_.push_back(slot);
      ++live_;
      out.data[k] = id;
    }
  }
  refresh_lean(bp::Changes::everything());
  return out;
}

void IndexCore::remove(const py::object& ids) {
  UseCounter::Writing w(use_);
  std::vector<std::uint32_t> id_list = id_vector(ids);
  std::vector<std::uint32_t> sorted = id_list;
  std::sort(sorted.begin(), sorted.end());
  if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end())
    throw BadInput("ids: id " + std::to_string(*std::adjacent_find(sorted.begin(), sorted.end())) +
                   " is given twice");
  if (structure_) {
    py::gil_scoped_release nogil;
    for (std::uint32_t id : id_list) {
      structure_->remove(handle_of_id_[id]);
      handle_of_id_[id] = bp::Handle{};
      slot_of_id_[id] = kGone;
      --live_;
    }
    dirty_ = true;
    return;
  }
  own();
  {
    py::gil_scoped_release nogil;
    for (std::uint32_t id : id_list) {
      const std::uint32_t slot = slot_of_id_[id];
      const std::uint32_t last = static_cast<std::uint32_t>(id_of_slot_.size() - 1);
      if (slot != last) {
        copy_slot(last, slot);
        id_of_slot_[slot] = id_of_slot_[last];
        slot_of_id_[id_of_slot_[slot]] = slot;
        identity_ = false;
      }
      pop_slot();
      id_of_slot_.pop_back();
      slot_of_id_[id] = kGone;
      --live_;
    }
  }
  refresh_lean(bp::Changes::everything());
}

void IndexCore::set_filters(const py::object& ids, const py::buffer& groups,
                            const py::buffer& masks) {
  UseCounter::Writing w(use_);
  const std::vector<std::uint32_t> id_list = ids.is_none() ? live_ids() : id_vector(ids);
  const std::vector<std::uint32_t> g = filter_column(groups, "groups", id_list.size());
  const std::vector<std::uint32_t> m = filter_column(masks, "masks", id_list.size());
  if (structure_) {
    py::gil_scoped_release nogil;
    for (std::size_t k = 0; k < id_list.size(); ++k)
      structure_->set_filter(handle_of_id_[id_list[k]], {g[k], m[k]});
    dirty_ = true;
    return;
  }
  if (group_.empty()) {
    group_.assign(id_of_slot_.size(), bp::Filter{}.group);
    mask_.assign(id_of_slot_.size(), bp::Filter{}.mask);
  }
  for (std::size_t k = 0; k < id_list.size(); ++k) {
    group_[slot_of_id_[id_list[k]]] = g[k];
    mask_[slot_of_id_[id_list[k]]] = m[k];
  }
  bind_filters();
  // The tracker reads the filters as it hands the pairs over: nothing moved.
  refresh_lean(bp::Changes::only({}));
}

IntArray IndexCore::pairs(bool sorted) {
  UseCounter::Reading r(use_);
  std::shared_ptr<const PairVec> snap = snapshot();
  py::gil_scoped_release nogil;
  if (!sorted) return to_int_array(*snap);
  PairVec copy = *snap;
  sort_pairs(copy, next_id_);
  return to_int_array(copy);
}

std::uint64_t IndexCore::count_pairs() {
  UseCounter::Reading r(use_);
  return snapshot()->size();
}

PairChunks IndexCore::iter_pairs(std::size_t chunk) {
  if (chunk == 0) throw BadInput("chunk: must be at least 1");
  UseCounter::Reading r(use_);
  return {snapshot(), 0, chunk};
}

IntArray IndexCore::query(const py::buffer& centers, const py::object& radii,
                          const py::object& half, const py::object& kinds) {
  UseCounter::Reading r(use_);
  ObjectArrays o = object_arrays(centers, radii, half, kinds, "other_centers", "other_radii",
                                 "other_half_extents");
  PairVec out;
  {
    py::gil_scoped_release nogil;
    if (structure_) {
      std::vector<std::uint32_t> hits;
      for (std::size_t q = 0; q < o.objects.count; ++q) {
        hits.clear();
        structure_->query(o.objects.shape(q), [&](bp::Handle h) {
          hits.push_back(id_of_index_[h.index]);
          return true;
        });
        std::sort(hits.begin(), hits.end());
        for (std::uint32_t id : hits) out.push_back({static_cast<std::uint32_t>(q), id});
      }
    } else {
      // A query's objects have no filters: the index's are not applied.
      bp::Objects mine = lean_objects();
      mine.groups = {};
      mine.masks = {};
      bp::find_pairs(o.objects, mine, out, array_options(threads_, true));
      if (!identity_) {
        for (bp::IndexPair& p : out) p.j = id_of_slot_[p.j];
        sort_pairs(out, o.objects.count);
      }
    }
  }
  return to_int_array(out);
}

IntArray IndexCore::query_box(const std::vector<double>& lo, const std::vector<double>& hi) {
  UseCounter::Reading r(use_);
  const bp::Shape box = checked_box(lo, hi);
  std::vector<std::uint32_t> ids;
  {
    py::gil_scoped_release nogil;
    if (structure_) {
      structure_->query(box, [&](bp::Handle h) {
        ids.push_back(id_of_index_[h.index]);
        return true;
      });
    } else {
      ids = bp::query(lean_objects(), box);
      if (!identity_)
        for (std::uint32_t& s : ids) s = id_of_slot_[s];
    }
    std::sort(ids.begin(), ids.end());
  }
  return ids_array(ids);
}

py::tuple IndexCore::ray_cast(const py::buffer& origins, const py::buffer& directions,
                              const py::object& tmax, const py::object& ray_masks, bool all_hits,
                              unsigned threads) {
  UseCounter::Reading r(use_);
  const std::vector<bp::Ray> rays = ray_arrays(origins, directions, tmax, ray_masks);
  if (structure_) return cast(*structure_, rays, all_hits, threads, &id_of_index_);
  // The tracker's caster over the objects of its last call, built at the
  // first cast after a change (concurrent casts share it: a change needs
  // the index to itself, so none runs meanwhile).
  const bp::arrays::RayCaster* caster = nullptr;
  {
    py::gil_scoped_release nogil;
    std::lock_guard<std::mutex> lock(mu_);
    caster = &tracker_->ray_caster(lean_objects());
  }
  return cast_lean(*caster, rays, all_hits, threads, identity_ ? nullptr : &id_of_slot_);
}

std::size_t IndexCore::memory_bytes() {
  UseCounter::Reading r(use_);
  if (structure_) return structure_->memory_bytes();
  return tracker_->memory_bytes() + owned_bytes();
}

void IndexCore::validate() {
  UseCounter::Reading r(use_);
  py::gil_scoped_release nogil;
  if (structure_) {
    structure_->validate();
  } else {
    std::lock_guard<std::mutex> lock(mu_);
    tracker_->validate(lean_objects());
  }
}

std::vector<std::uint32_t> IndexCore::live_ids() const {
  std::vector<std::uint32_t> v;
  v.reserve(live_);
  for (std::uint32_t id = 0; id < next_id_; ++id)
    if (alive(id)) v.push_back(id);
  return v;
}

std::vector<std::uint32_t> IndexCore::id_vector(const py::object& ids_obj) {
  const py::buffer_info info = ids_obj.cast<py::buffer>().request();
  if (info.ndim != 1 || info.itemsize != 8 || !(info.format == "q" || info.format == "l"))
    throw BadInput("ids: expected a 1-D array of int64, got format '" + info.format + "' shape " +
                   shape_text(info));
  std::vector<std::uint32_t> out(static_cast<std::size_t>(info.shape[0]));
  for (std::size_t k = 0; k < out.size(); ++k) {
    std::int64_t v;
    std::memcpy(
        &v, static_cast<const char*>(info.ptr) + static_cast<std::ptrdiff_t>(k) * info.strides[0],
        sizeof v);
    if (v < 0 || v >= static_cast<std::int64_t>(next_id_) || !alive(static_cast<std::uint32_t>(v)))
      throw BadInput("ids[" + std::to_string(k) + "] is " + std::to_string(v) +
                     ", not the id of an object in the index");
    out[k] = static_cast<std::uint32_t>(v);
  }
  return out;
}

std::vector<std::uint32_t> IndexCore::slots_of(const py::object& ids) {
  std::vector<std::uint32_t> v = id_vector(ids);
  for (std::uint32_t& id : v) id = slot_of_id_[id];
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

ObjectArrays IndexCore::with_current_sizes(const py::buffer& centers, const py::object& radii,
                                           const py::object& half, std::size_t rows) {
  if (radii.is_none() && half.is_none()) {
    // Centres only: apply_moves keeps each object's own size.
    ObjectArrays o;
    o.centers = real_array(centers, "centers", 3, false, rows);
    {
      py::gil_scoped_release nogil;
      check_values(o.centers, "centers", false);
    }
    o.objects.count = rows;
    o.objects.x = o.centers.column(0);
    o.objects.y = o.centers.column(1);
    o.objects.z = o.centers.column(2);
    keep_sizes_ = true;
    return o;
  }
  if (!radii.is_none() && !half.is_none())
    throw BadInput("give radii or half_extents to resize, not both (an object keeps its kind)");
  ObjectArrays o = object_arrays(centers, radii, half, py::none());
  if (o.objects.count != rows)
    throw BadInput("centers: expected " + std::to_string(rows) + " rows, got " +
                   std::to_string(o.objects.count));
  keep_sizes_ = false;
  return o;
}

void IndexCore::apply_moves(const std::vector<std::uint32_t>& ids, const ObjectArrays& o) {
  const bool keep = keep_sizes_;
  if (structure_) {
    std::vector<bp::Move> moves(ids.size());
    py::gil_scoped_release nogil;
    for (std::size_t k = 0; k < ids.size(); ++k) {
      const bp::Handle h = handle_of_id_[ids[k]];
      moves[k] = {h, moved_shape(structure_->shape(h), o, k, keep)};
      if (!bp::is_valid(moves[k].shape)) throw BadInput(kind_mismatch(ids[k]));
    }
    structure_->update(moves);
    dirty_ = true;
    return;
  }
  // Every new shape is made and checked before anything changes, so a
  // refused update leaves the index as it was.
  std::vector<bp::Shape> shapes(ids.size());
  std::vector<std::uint32_t> slots(ids.size());
  {
    py::gil_scoped_release nogil;
    const bp::Objects& now = lean_objects();
    for (std::size_t k = 0; k < ids.size(); ++k) {
      slots[k] = slot_of_id_[ids[k]];
      shapes[k] = moved_shape(now.shape(slots[k]), o, k, keep);
      if (!bp::is_valid(shapes[k])) throw BadInput(kind_mismatch(ids[k]));
    }
  }
  own();
  {
    py::gil_scoped_release nogil;
    for (std::size_t k = 0; k < ids.size(); ++k) set_shape(slots[k], shapes[k]);
    std::sort(slots.begin(), slots.end());
    slots.erase(std::unique(slots.begin(), slots.end()), slots.end());
  }
  refresh_lean(ids.size() == live_ ? bp::Changes::everything() : bp::Changes::only(slots));
}

std::string IndexCore::kind_mismatch(std::uint32_t id) {
  return "object " + std::to_string(id) +
         ": a sphere takes radii, a box half_extents (an update keeps the kind)";
}

bp::Shape IndexCore::moved_shape(const bp::Shape& old, const ObjectArrays& o, std::size_t k,
                                 bool keep) {
  bp::Shape s = old;
  s.center = {o.objects.x.at(k), o.objects.y.at(k), o.objects.z.at(k)};
  if (keep) return s;
  if (old.is_sphere()) {
    if (o.objects.radius.empty()) {
      s.half = {-1, -1, -1};  // refused by the caller: a sphere needs a radius
    } else {
      const double r = o.objects.radius.at(k);
      s.half = {r, r, r};
    }
  } else {
    if (o.objects.half_x.empty())
      s.half = {-1, -1, -1};
    else
      s.half = {o.objects.half_x.at(k), o.objects.half_y.at(k), o.objects.half_z.at(k)};
  }
  return s;
}

void IndexCore::refresh_lean(const bp::Changes& changes) {
  auto next = std::make_shared<PairVec>();
  {
    py::gil_scoped_release nogil;
    std::lock_guard<std::mutex> lock(mu_);
    if (snap_ && snap_.use_count() == 1) {
      // No iterator holds the last list: reuse its room.
      *next = std::move(*std::const_pointer_cast<PairVec>(snap_));
      next->clear();
    }
    tracker_->find_pairs(lean_objects(), *next, changes);
    if (!identity_) {
      for (bp::IndexPair& p : *next) {
        p.i = id_of_slot_[p.i];
        p.j = id_of_slot_[p.j];
        if (p.i > p.j) std::swap(p.i, p.j);
      }
    }
    snap_ = std::move(next);
  }
}

const bp::Objects& IndexCore::lean_objects() const {
  return borrowed_ ? borrowed_->objects : owned_objects_;
}

void IndexCore::own() {
  if (!borrowed_) return;
  const bp::Objects& b = borrowed_->objects;
  const std::size_t n = b.count;
  {
    py::gil_scoped_release nogil;
    xyz_.resize(3 * n);
    r_.resize(n);
    half_.resize(3 * n);
    kind_.resize(n);
    spheres_ = boxes_ = 0;
    for (std::size_t i = 0; i < n; ++i) set_shape_raw(i, b.shape(i), true);
  }
  borrowed_.reset();
  borrowed_py_.clear();
  rebind_owned();
}

bp::Shape IndexCore::owned_shape(std::size_t s) const {
  const bp::Vec3 c{xyz_[3 * s], xyz_[3 * s + 1], xyz_[3 * s + 2]};
  if (kind_[s] == 0) return bp::Shape::sphere(c, r_[s]);
  return bp::Shape::box(c, {half_[3 * s], half_[3 * s + 1], half_[3 * s + 2]});
}

void IndexCore::set_shape_raw(std::size_t s, const bp::Shape& sh, bool count) {
  xyz_[3 * s] = sh.center.x;
  xyz_[3 * s + 1] = sh.center.y;
  xyz_[3 * s + 2] = sh.center.z;
  r_[s] = sh.is_sphere() ? sh.radius() : 0;
  half_[3 * s] = sh.half.x;
  half_[3 * s + 1] = sh.half.y;
  half_[3 * s + 2] = sh.half.z;
  kind_[s] = sh.is_sphere() ? 0 : 1;
  if (count) (sh.is_sphere() ? spheres_ : boxes_)++;
}

void IndexCore::push_shape(const bp::Shape& sh) {
  const std::size_t s = r_.size();
  xyz_.resize(3 * s + 3);
  r_.resize(s + 1);
  half_.resize(3 * s + 3);
  kind_.resize(s + 1);
  set_shape_raw(s, sh, true);
  rebind_owned();
}

void IndexCore::copy_slot(std::size_t from, std::size_t to) {
  (kind_[to] == 0 ? spheres_ : boxes_)--;
  set_shape_raw(to, owned_shape(from), true);
  if (!group_.empty()) {
    group_[to] = group_[from];
    mask_[to] = mask_[from];
  }
}

void IndexCore::pop_slot() {
  const std::size_t s = r_.size() - 1;
  (kind_[s] == 0 ? spheres_ : boxes_)--;
  if (!group_.empty()) {
    group_.resize(s);
    mask_.resize(s);
  }
  xyz_.resize(3 * s);
  r_.resize(s);
  half_.resize(3 * s);
  kind_.resize(s);
  rebind_owned();
}

void IndexCore::rebind_owned() {
  bp::Objects& o = owned_objects_;
  o = bp::Objects{};
  o.count = r_.size();
  o.x = bp::Column::of(xyz_.data(), 3);
  o.y = bp::Column::of(xyz_.data() + 1, 3);
  o.z = bp::Column::of(xyz_.data() + 2, 3);
  if (spheres_ > 0 || boxes_ == 0) o.radius = bp::Column::of(r_.data());
  if (boxes_ > 0) {
    o.half_x = bp::Column::of(half_.data(), 3);
    o.half_y = bp::Column::of(half_.data() + 1, 3);
    o.half_z = bp::Column::of(half_.data() + 2, 3);
  }
  if (spheres_ > 0 && boxes_ > 0) o.kind = kind_.data();
  if (o.radius.data == nullptr && boxes_ == 0) {
    // An empty index: a sphere set of nothing.
    static const double kNone = 0;
    o.radius = bp::Column::of(&kNone, 0);
  }
  bind_filters();
}

void IndexCore::bind_filters() {
  const std::span<const std::uint32_t> g = group_, m = mask_;
  owned_objects_.groups = g;
  owned_objects_.masks = m;
  if (borrowed_) {
    borrowed_->objects.groups = g;
    borrowed_->objects.masks = m;
  }
}

std::size_t IndexCore::owned_bytes() const {
  return xyz_.capacity() * 8 + r_.capacity() * 8 + half_.capacity() * 8 + kind_.capacity() +
         (group_.capacity() + mask_.capacity()) * 4 + id_of_slot_.capacity() * 4 +
         slot_of_id_.capacity() * 4;
}

bp::Aabb IndexCore::world_of(const bp::Objects& o) {
  // The structures that subdivide a region take the objects' bounding box
  // as their world hint (the default, [0, 1000]^3, would put unit-cube
  // data in one cell).
  bp::Aabb w{{0, 0, 0}, {1, 1, 1}};
  if (o.count == 0) return w;
  constexpr double inf = std::numeric_limits<double>::infinity();
  w = {{inf, inf, inf}, {-inf, -inf, -inf}};
  for (std::size_t i = 0; i < o.count; ++i) {
    const bp::Shape s = o.shape(i);
    for (int a = 0; a < 3; ++a) {
      w.lo[a] = std::min(w.lo[a], s.center[a] - s.half[a]);
      w.hi[a] = std::max(w.hi[a], s.center[a] + s.half[a]);
    }
  }
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(w.lo[a]) || !std::isfinite(w.hi[a])) return bp::Config{}.world;
    if (!(w.hi[a] > w.lo[a])) {
      w.lo[a] -= 0.5;
      w.hi[a] += 0.5;
    }
  }
  return w;
}

void IndexCore::set_id_of_index(std::uint32_t index, std::uint32_t id) {
  if (id_of_index_.size() <= index) id_of_index_.resize(index + 1, kGone);
  id_of_index_[index] = id;
}

std::shared_ptr<const PairVec> IndexCore::snapshot() {
  py::gil_scoped_release nogil;
  std::lock_guard<std::mutex> lock(mu_);
  if (structure_ && dirty_) {
    std::vector<bp::HandlePair> hp;
    structure_->find_pairs(hp);
    auto next = std::make_shared<PairVec>(hp.size());
    for (std::size_t k = 0; k < hp.size(); ++k) {
      std::uint32_t a = id_of_index_[hp[k].a.index], b = id_of_index_[hp[k].b.index];
      if (a > b) std::swap(a, b);
      (*next)[k] = {a, b};
    }
    snap_ = std::move(next);
    dirty_ = false;
  }
  return snap_;
}

}  // namespace broadphase_python
