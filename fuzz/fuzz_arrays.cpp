// The lean path (arrays.hpp) over fuzzed arrays: up to 40 spheres and boxes
// at nasty coordinates, stored as the caller would store them (double or
// float; rows of xyz, separate columns, or strided records with padding;
// one radius for all; a kind byte per object), sometimes with a bad value
// (NaN, infinity, a negative size, a float that overflows, an unknown kind).
// Checked against a brute force over the same shapes with overlaps() of
// geometry.hpp:
// - a bad value is refused with InvalidObjects naming the first bad object;
// - one-shot pairs (1 and 2 threads: the same pairs in the same order;
//   sorted or not), bipartite pairs of two halves, a query;
// - a PairTracker over up to 12 frames of moves, teleports, resizes, kind
//   changes, appends and removals, told which objects changed or not;
//   validate() after every call; a refused call leaves it as it was.
// The Python module hands numpy arrays to these same calls as `Objects`
// (float32/float64, strided views, a scalar radius), so its inputs are
// these.
#include <algorithm>
#include <broadphase/arrays/arrays.hpp>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "support.hpp"

namespace {

using namespace broadphase;

enum class Layout : std::uint8_t { rows, columns, records };

// The caller's storage: one buffer of T per column, or one of records.
template <class T>
struct Store {
  Layout layout = Layout::rows;
  bool scalar_radius = false;  // one radius for all (stride 0)
  bool mixed = false;          // a kind byte per object
  bool boxes = false;          // without kinds: all boxes (else all spheres)
  std::vector<Shape> shapes;   // what the caller meant (before storing)
  std::vector<T> buf;
  std::vector<std::uint8_t> kinds;

  // Record fields: x y z r hx hy hz, then one pad.
  static constexpr int kFields = 8;

  Objects view() {
    const std::size_t n = shapes.size();
    buf.assign(n * kFields + kFields, T(0));
    kinds.assign(n + 1, 0);
    Objects o;
    o.count = n;
    auto put = [&](std::size_t i, int field, double v) {
      T* p = column_base(field, n);
      p[static_cast<std::ptrdiff_t>(i) * stride(field)] = static_cast<T>(v);
    };
    for (std::size_t i = 0; i < n; ++i) {
      const Shape& s = shapes[i];
      put(i, 0, s.center.x);
      put(i, 1, s.center.y);
      put(i, 2, s.center.z);
      if (s.kind == ShapeKind::sphere) {
        if (!scalar_radius || i == 0) put(i, 3, s.radius());
      } else {
        put(i, 4, s.half.x);
        put(i, 5, s.half.y);
        put(i, 6, s.half.z);
      }
      kinds[i] = s.kind == ShapeKind::sphere ? 0 : 1;
    }
    const auto col = [&](int field, std::ptrdiff_t elems) {
      return Column::of(static_cast<const T*>(column_base(field, n)), elems);
    };
    o.x = col(0, stride(0));
    o.y = col(1, stride(1));
    o.z = col(2, stride(2));
    if (mixed || !boxes) o.radius = col(3, scalar_radius ? 0 : stride(3));
    if (mixed || boxes) {
      o.half_x = col(4, stride(4));
      o.half_y = col(5, stride(5));
      o.half_z = col(6, stride(6));
    }
    if (mixed) o.kind = kinds.data();
    return o;
  }

  // Elements between objects in `field`'s column.
  std::ptrdiff_t stride(int field) const {
    if (layout == Layout::rows) return field == 3 ? 1 : 3;
    return layout == Layout::records ? kFields : 1;
  }
  // rows: n x 3 rows for the centres and for the half-extents, a dense
  // column of radii; columns: one block of n per field; records:
  // interleaved fields.
  T* column_base(int field, std::size_t n) {
    switch (layout) {
      case Layout::rows:
        // centres at [0, 3n), radii at [3n, 4n), half-extents at [4n, 7n).
        if (field < 3) return buf.data() + field;
        if (field == 3) return buf.data() + 3 * n;
        return buf.data() + 4 * n + (field - 4);
      case Layout::columns:
        return buf.data() + static_cast<std::size_t>(field) * n;
      default:
        return buf.data() + field;
    }
  }
};

// The shape as stored in T and read back (what the library must see).
template <class T>
Shape stored(const Shape& s) {
  auto r = [](double v) { return static_cast<double>(static_cast<T>(v)); };
  if (s.kind == ShapeKind::sphere)
    return Shape::sphere({r(s.center.x), r(s.center.y), r(s.center.z)}, r(s.radius()));
  return Shape::box({r(s.center.x), r(s.center.y), r(s.center.z)},
                    {r(s.half.x), r(s.half.y), r(s.half.z)});
}

bool finite_and_valid(const Shape& s) {
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(s.center[a])) return false;
  if (s.kind == ShapeKind::sphere) return std::isfinite(s.radius()) && s.radius() >= 0;
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(s.half[a]) || s.half[a] < 0) return false;
  return true;
}

// What the library must see for object i, with the scalar radius applied.
template <class T>
std::vector<Shape> seen(const Store<T>& st) {
  std::vector<Shape> out;
  for (std::size_t i = 0; i < st.shapes.size(); ++i) {
    Shape s = stored<T>(st.shapes[i]);
    if (s.kind == ShapeKind::sphere && st.scalar_radius)
      s = Shape::sphere(s.center, stored<T>(st.shapes[0]).radius());
    out.push_back(s);
  }
  return out;
}

std::size_t first_bad(const std::vector<Shape>& shapes) {
  for (std::size_t i = 0; i < shapes.size(); ++i)
    if (!finite_and_valid(shapes[i])) return i;
  return SIZE_MAX;
}

std::vector<IndexPair> brute(const std::vector<Shape>& s) {
  std::vector<IndexPair> out;
  for (std::uint32_t i = 0; i < s.size(); ++i)
    for (std::uint32_t j = i + 1; j < s.size(); ++j)
      if (overlaps(s[i], s[j])) out.push_back({i, j});
  return out;
}

void sort_pairs(std::vector<IndexPair>& p) {
  std::sort(p.begin(), p.end(), [](const IndexPair& a, const IndexPair& b) {
    return a.i != b.i ? a.i < b.i : a.j < b.j;
  });
}

void expect_pairs(std::vector<IndexPair> got, const std::vector<IndexPair>& want,
                  const char* what) {
  sort_pairs(got);
  if (got != want)
    fuzz::finding(std::string(what) + ": " + std::to_string(got.size()) + " pairs, brute force " +
                  std::to_string(want.size()));
}

// Runs `call`; a bad value must be refused naming `bad`, a good set must not be.
template <class F>
bool accepted(std::size_t bad, F&& call, const char* what) {
  try {
    call();
  } catch (const InvalidObjects& e) {
    if (bad == SIZE_MAX) fuzz::finding(std::string(what) + ": good objects refused: " + e.what());
    if (e.index() != bad)
      fuzz::finding(std::string(what) + ": refusal names object " + std::to_string(e.index()) +
                    ", the first bad one is " + std::to_string(bad));
    if (std::string(e.what()).empty())
      fuzz::finding(std::string(what) + ": refusal without a message");
    return false;
  }
  if (bad != SIZE_MAX)
    fuzz::finding(std::string(what) + ": object " + std::to_string(bad) +
                  " is bad but was accepted");
  return true;
}

Shape shape_for(FuzzedDataProvider& in, bool mixed, bool boxes) {
  Shape s = fuzz::nasty_shape(in);
  if (!mixed) {
    const Vec3 c = s.center;
    const double h = s.half.x;
    s = boxes ? Shape::box(c, {h, s.kind == ShapeKind::box ? s.half.y : h,
                               s.kind == ShapeKind::box ? s.half.z : h})
              : Shape::sphere(c, h);
  }
  return s;
}

// Sometimes spoils one value: NaN, infinity, a negative size, a value too
// large for float, or (with kinds) an unknown kind byte (returned as true).
bool spoil(FuzzedDataProvider& in, Shape& s) {
  switch (in.ConsumeIntegral<std::uint8_t>() % 16) {
    case 0:
      s.center.y = std::numeric_limits<double>::quiet_NaN();
      break;
    case 1:
      s.center.z = -std::numeric_limits<double>::infinity();
      break;
    case 2:
      if (s.kind == ShapeKind::sphere)
        s = Shape::sphere(s.center, -1);
      else
        s.half.z = -0.5;
      break;
    case 3:
      s.center.x = 1e300;  // overflows a float; fine in double
      break;
    case 4:
      return true;
    default:
      break;
  }
  return false;
}

template <class T>
void run(FuzzedDataProvider& in) {
  Store<T> st;
  st.layout = static_cast<Layout>(in.ConsumeIntegral<std::uint8_t>() % 3);
  st.mixed = in.ConsumeBool();
  st.boxes = !st.mixed && in.ConsumeBool();
  st.scalar_radius = !st.mixed && !st.boxes && in.ConsumeBool();
  const unsigned threads = in.ConsumeBool() ? 2 : 1;
  const int n = in.ConsumeIntegralInRange(0, 40);
  for (int i = 0; i < n && in.remaining_bytes() > 0; ++i)
    st.shapes.push_back(shape_for(in, st.mixed, st.boxes));
  // A bad value at a fuzzed place, one input in four.
  std::size_t bad_kind = SIZE_MAX;
  if (!st.shapes.empty() && in.ConsumeIntegral<std::uint8_t>() % 4 == 0) {
    const std::size_t k = in.ConsumeIntegral<std::uint8_t>() % st.shapes.size();
    if (spoil(in, st.shapes[k]) && st.mixed) bad_kind = k;
  }
  Objects o = st.view();
  if (bad_kind != SIZE_MAX) st.kinds[bad_kind] = 2;
  const std::vector<Shape> shapes = seen(st);
  std::size_t bad = first_bad(shapes);
  if (bad_kind != SIZE_MAX) bad = std::min(bad, bad_kind);

  // One-shot, on 1 and `threads` threads: same pairs, same order.
  std::vector<IndexPair> one, many;
  ArrayOptions opt;
  opt.sorted = in.ConsumeBool();
  if (!accepted(
          bad, [&] { find_pairs(o, one, opt); }, "find_pairs"))
    return;
  opt.threads = threads;
  find_pairs(o, many, opt);
  if (one != many) fuzz::finding("find_pairs: the order differs between 1 and 2 threads");
  for (const IndexPair& p : one)
    if (!(p.i < p.j)) fuzz::finding("find_pairs: a pair with i >= j");
  const std::vector<IndexPair> want = brute(shapes);
  expect_pairs(one, want, "find_pairs");

  // Bipartite: the first half against the second.
  const std::size_t half = shapes.size() / 2;
  Objects a = o, b = o;
  a.count = half;
  b.count = shapes.size() - half;
  auto shift = [&](Column& c) {
    if (!c.empty())
      c.data =
          static_cast<const unsigned char*>(c.data) + static_cast<std::ptrdiff_t>(half) * c.stride;
  };
  for (Column* c : {&b.x, &b.y, &b.z, &b.radius, &b.half_x, &b.half_y, &b.half_z}) shift(*c);
  if (b.kind != nullptr) b.kind += half;
  std::vector<IndexPair> bip;
  find_pairs(a, b, bip);
  std::vector<IndexPair> bip_want;
  for (std::uint32_t i = 0; i < half; ++i)
    for (std::uint32_t j = static_cast<std::uint32_t>(half); j < shapes.size(); ++j)
      if (overlaps(shapes[i], shapes[j]))
        bip_want.push_back({i, static_cast<std::uint32_t>(j - half)});
  expect_pairs(bip, bip_want, "bipartite find_pairs");

  // A query.
  const Shape q = fuzz::nasty_shape(in);
  std::vector<std::uint32_t> hits = query(o, q), hits_want;
  for (std::uint32_t i = 0; i < shapes.size(); ++i)
    if (overlaps(q, shapes[i])) hits_want.push_back(i);
  if (hits != hits_want)
    fuzz::finding("query: " + std::to_string(hits.size()) + " objects, brute force " +
                  std::to_string(hits_want.size()));

  // The tracker over frames.
  ArrayOptions topt;
  topt.threads = threads;
  topt.skin = in.ConsumeBool() ? 0 : 4.0;
  PairTracker tracker(topt);
  std::vector<IndexPair> got;
  tracker.find_pairs(o, got);
  expect_pairs(got, want, "tracker, first call");
  tracker.validate(o);
  // The caller's shapes at the last accepted call (edits may make a float
  // overflow, as a spoilt value does).
  std::vector<Shape> last_good = st.shapes;
  for (int frame = 0; frame < 12 && in.remaining_bytes() > 0; ++frame) {
    std::vector<std::uint32_t> changed;
    const int edits = in.ConsumeIntegralInRange(0, 6);
    for (int e = 0; e < edits && in.remaining_bytes() > 0; ++e) {
      const std::uint8_t op = in.ConsumeIntegral<std::uint8_t>() % 6;
      if (op == 0 && st.shapes.size() < 48) {  // append
        st.shapes.push_back(shape_for(in, st.mixed, st.boxes));
        changed.push_back(static_cast<std::uint32_t>(st.shapes.size() - 1));
      } else if (op == 1 && !st.shapes.empty()) {  // remove k: the last one takes its place
        const std::size_t k = in.ConsumeIntegral<std::uint8_t>() % st.shapes.size();
        st.shapes[k] = st.shapes.back();
        st.shapes.pop_back();
        if (k < st.shapes.size()) changed.push_back(static_cast<std::uint32_t>(k));
      } else if (!st.shapes.empty()) {  // move a little, teleport, resize or change kind
        const std::size_t k = in.ConsumeIntegral<std::uint8_t>() % st.shapes.size();
        Shape& s = st.shapes[k];
        if (op == 2) {
          s.center.x += 0.25;
        } else if (op == 3) {
          s = shape_for(in, st.mixed, st.boxes);
        } else if (op == 4) {
          if (s.kind == ShapeKind::sphere)
            s = Shape::sphere(s.center, fuzz::nasty_size(in));
          else
            s.half.y = fuzz::nasty_size(in);
        } else {
          s = shape_for(in, st.mixed, st.boxes);
        }
        changed.push_back(static_cast<std::uint32_t>(k));
      }
    }
    // With one radius for all, a change of object 0 changes every sphere:
    // the caller then says that everything may have changed.
    const bool zero_changed = std::find(changed.begin(), changed.end(), 0u) != changed.end();
    const bool tell_all = in.ConsumeBool() || (st.scalar_radius && zero_changed);
    const bool spoilt = !st.shapes.empty() && in.ConsumeIntegral<std::uint8_t>() % 8 == 0;
    std::size_t spoilt_kind = SIZE_MAX;
    if (spoilt) {
      const std::size_t k = in.ConsumeIntegral<std::uint8_t>() % st.shapes.size();
      if (spoil(in, st.shapes[k]) && st.mixed) spoilt_kind = k;
      changed.push_back(static_cast<std::uint32_t>(k));
    }
    Objects now = st.view();
    if (spoilt_kind != SIZE_MAX) st.kinds[spoilt_kind] = 2;
    const std::vector<Shape> now_shapes = seen(st);
    std::size_t now_bad = first_bad(now_shapes);
    if (spoilt_kind != SIZE_MAX) now_bad = std::min(now_bad, spoilt_kind);
    // Indices past the new count (changed, then removed) are not listed.
    std::vector<std::uint32_t> listed;
    for (std::uint32_t k : changed)
      if (k < st.shapes.size()) listed.push_back(k);
    const Changes ch = tell_all ? Changes::everything() : Changes::only(listed);
    got.clear();
    if (!accepted(
            now_bad, [&] { tracker.find_pairs(now, got, ch); }, "tracker")) {
      // Refused: the tracker is as before; go on from the last good arrays,
      // telling it everything (the caller's arrays changed back).
      st.shapes = last_good;
      now = st.view();
      got.clear();
      tracker.find_pairs(now, got, Changes::everything());
      expect_pairs(got, brute(seen(st)), "tracker after a refused call");
      tracker.validate(now);
      o = now;
      continue;
    }
    expect_pairs(got, brute(now_shapes), "tracker");
    try {
      tracker.validate(now);
    } catch (const std::exception& e) {
      fuzz::finding(std::string("tracker validate(): ") + e.what());
    }
    last_good = st.shapes;
    o = now;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  if (in.ConsumeBool())
    run<double>(in);
  else
    run<float>(in);
  return 0;
}
