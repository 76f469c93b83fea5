#include <sys/stat.h>

#include <algorithm>
#include <broadphase/scenes/excerpt.hpp>
#include <broadphase/scenes/output_file.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <numeric>
#include <sstream>

namespace broadphase {

bool Scene::has_boxes() const {
  for (const Shape& s : objects)
    if (s.kind == ShapeKind::box) return true;
  return false;
}

bool Scene::has_filters() const {
  for (const Filter& f : filters)
    if (!(f == Filter{})) return true;
  return false;
}

int Scene::version() const {
  return has_filters() || has_rays() || is_periodic() ? 3 : has_boxes() ? 2 : 1;
}

std::array<bool, 3> parse_periodic_axes(std::string_view axes) {
  if (axes.empty()) throw std::invalid_argument("names no axis (x, y and/or z)");
  std::array<bool, 3> out{false, false, false};
  for (char c : axes) {
    const int a = c == 'x' ? 0 : c == 'y' ? 1 : c == 'z' ? 2 : -1;
    if (a < 0)
      throw std::invalid_argument("'" + excerpt(axes) + "' has " + excerpt(std::string(1, c)) +
                                  ", which is not an axis (x, y, z)");
    if (out[a])
      throw std::invalid_argument("'" + excerpt(axes) + "' names " + std::string(1, c) + " twice");
    out[a] = true;
  }
  return out;
}

std::string periodic_axes_text(const std::array<bool, 3>& axes) {
  std::string out;
  for (int a = 0; a < 3; ++a)
    if (axes[a]) out += "xyz"[a];
  return out;
}

namespace {

// Splits a line into whitespace-separated fields.
std::vector<std::string_view> fields_of(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    std::size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
    if (j > i) out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

class LineReader {
 public:
  LineReader(std::istream& in, const std::string& name) : in_(in), name_(name) {}

  // Next line that is neither blank nor a comment; false at end of input.
  bool next(std::vector<std::string_view>& fields) {
    while (std::getline(in_, line_)) {
      ++number_;
      fields = fields_of(line_);
      if (fields.empty() || fields[0].front() == '#') continue;
      return true;
    }
    return false;
  }
  bool raw(std::string& line) {
    if (!std::getline(in_, line)) return false;
    ++number_;
    return true;
  }
  [[noreturn]] void fail(const std::string& why) const {
    throw SceneError(name_ + ":" + std::to_string(number_) + ": " + why);
  }
  double number(std::string_view text, const char* what) const {
    double v = 0;
    // A leading '+' is a sign like '-' (from_chars takes only '-').
    const std::string_view digits =
        text.size() > 1 && text[0] == '+' && text[1] != '-' && text[1] != '+' ? text.substr(1)
                                                                              : text;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
    if (ec == std::errc::result_out_of_range)
      fail(std::string(what) + " " + excerpt(text) + " is out of the range of a double");
    if (ec != std::errc{} || end != digits.data() + digits.size())
      fail(std::string(what) + " " + excerpt(text) + " is not a number");
    if (!std::isfinite(v)) fail(std::string(what) + " is " + excerpt(text) + ", not finite");
    return v;
  }
  int line() const { return number_; }

 private:
  std::istream& in_;
  const std::string& name_;
  std::string line_;
  int number_ = 0;
};

}  // namespace

namespace {

// A filter's bits: decimal (a leading 0 is not octal) or 0x/0X and hex
// digits, no sign, below 2^32.
std::uint32_t parse_bits(const LineReader& r, std::string_view text, const char* what) {
  std::string_view digits = text;
  int base = 10;
  if (digits.size() >= 2 && digits[0] == '0' && (digits[1] == 'x' || digits[1] == 'X')) {
    digits.remove_prefix(2);
    base = 16;
  }
  std::uint64_t v = 0;
  const bool only_digits =
      !digits.empty() && std::all_of(digits.begin(), digits.end(), [&](char c) {
        return base == 10 ? std::isdigit(static_cast<unsigned char>(c)) != 0
                          : std::isxdigit(static_cast<unsigned char>(c)) != 0;
      });
  if (!only_digits)
    r.fail(std::string(what) + " " + excerpt(text) +
           " is not an unsigned integer (decimal, or 0x and hex digits)");
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v, base);
  if (ec != std::errc{} || end != digits.data() + digits.size() || v > 0xffffffffull)
    r.fail(std::string(what) + " " + excerpt(text) + " is not below 2^32");
  return static_cast<std::uint32_t>(v);
}

// A count line's value: a whole number below 2^32.
std::uint64_t parse_count(const LineReader& r, std::string_view text, const char* what) {
  std::uint64_t count = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), count);
  if (ec != std::errc{} || end != text.data() + text.size() || count > 0xfffffffeull)
    r.fail(std::string(what) + " " + excerpt(text) + " is not a whole number below 2^32");
  return count;
}

// A ray's tmax: a number >= 0 or `inf`; -0 counts as 0.
double parse_tmax(const LineReader& r, std::string_view text) {
  const std::string_view digits = text.size() > 1 && text[0] == '+' ? text.substr(1) : text;
  if (digits == "inf" || digits == "infinity" || digits == "INF" || digits == "Inf")
    return std::numeric_limits<double>::infinity();
  const double v = r.number(text, "tmax");
  if (v < 0) r.fail("tmax " + excerpt(text) + " is negative");
  return v == 0 ? 0.0 : v;  // -0 counts as 0
}

// A ray line (its first field is "ray"): `ray ox oy oz dx dy dz tmax [filter M]`.
Ray parse_ray(const LineReader& r, const std::vector<std::string_view>& f) {
  if (f.size() != 8 && !(f.size() == 10 && f[8] == "filter")) {
    if (f.size() > 8 && f[8] == "filter")
      r.fail("'filter' on a ray line takes exactly one value, its mask M");
    r.fail("a ray line needs 7 numbers (ox oy oz dx dy dz tmax) and optionally 'filter M', got " +
           std::to_string(f.size() - 1) + " fields");
  }
  static const char* const kNames[] = {"ox", "oy", "oz", "dx", "dy", "dz"};
  double v[6];
  for (int i = 0; i < 6; ++i) v[i] = r.number(f[1 + i], kNames[i]);
  Ray ray;
  ray.origin = {v[0], v[1], v[2]};
  ray.dir = {v[3], v[4], v[5]};
  ray.tmax = parse_tmax(r, f[7]);
  if (f.size() == 10) ray.mask = parse_bits(r, f[9], "ray mask");
  const std::string why = ray_problem(ray);
  if (!why.empty()) r.fail("ray " + why);
  return ray;
}

}  // namespace

Scene parse_scene(std::istream& in, const std::string& name) {
  LineReader r(in, name);
  std::vector<std::string_view> f;
  std::string header;
  // The header must be line 1 exactly, so it is read raw, not skipped as blank.
  if (!r.raw(header)) r.fail("empty file; expected 'broadphase-scene 1', '2' or '3'");
  if (!header.empty() && header.back() == '\r') header.pop_back();
  // A UTF-8 byte order mark, as some editors write, is not part of the text.
  if (header.starts_with("\xEF\xBB\xBF")) header.erase(0, 3);
  if (header.find('\r') != std::string::npos)
    r.fail("lines end in a lone CR (\\x0d); the format wants LF or CRLF line ends; got " +
           excerpt(header));
  int version = 0;
  if (header == "broadphase-scene 1")
    version = 1;
  else if (header == "broadphase-scene 2")
    version = 2;
  else if (header == "broadphase-scene 3")
    version = 3;
  else
    r.fail("expected 'broadphase-scene 1', 'broadphase-scene 2' or 'broadphase-scene 3', got " +
           excerpt(header));
  Scene scene;
  auto expect_keyword = [&](const char* key) {
    if (!r.next(f)) r.fail(std::string("missing '") + key + " ...' line");
    if (f[0] != key) r.fail(std::string("expected '") + key + " ...', got " + excerpt(f[0]));
    if (f.size() > 2 && f[0] == "world" && f[2] == "periodic") return;
    if (f.size() != 2) r.fail(std::string("'") + key + "' takes exactly one value");
  };
  expect_keyword("world");
  scene.world = r.number(f[1], "world size");
  if (!(scene.world > 0)) r.fail("world size must be > 0");
  if (f.size() > 2) {
    // `world L periodic AXES` (version 3).
    if (version < 3) r.fail("a periodic world needs 'broadphase-scene 3'");
    if (f.size() == 3) r.fail("'periodic' needs its axes (x, y and/or z, e.g. 'periodic xyz')");
    if (f.size() > 4)
      r.fail("'world L periodic AXES' takes one word of axes, got " + excerpt(f[4]) + " after it");
    try {
      scene.periodic = parse_periodic_axes(f[3]);
    } catch (const std::invalid_argument& e) {
      r.fail(std::string("periodic axes ") + e.what());
    }
  }
  const double half_world = scene.world / 2;
  // On a periodic axis a: c in [0, L], every extent below L/2, |v| below L
  // (a periodic world is version 3: the object's fields start at f[1]).
  auto check_periodic = [&](const Shape& shape, const Vec3& v) {
    for (int a = 0; a < 3; ++a) {
      if (!scene.periodic[a]) continue;
      const char axis = "xyz"[a];
      if (!(shape.center[a] >= 0 && shape.center[a] <= scene.world))
        r.fail(std::string("centre ") + axis + " " + excerpt(f[1 + a]) +
               " is outside [0, L] on the periodic axis " + axis);
      if (!(shape.half[a] < half_world))
        r.fail(std::string(shape.is_sphere() ? "radius" : std::string("h") + axis) + " " +
               excerpt(f[1 + 3 + (shape.is_sphere() ? 0 : a)]) +
               " is not below L/2 on the periodic axis " + axis);
      if (!(std::fabs(v[a]) < scene.world))
        r.fail(std::string("v") + axis + " " + excerpt(f[1 + (shape.is_sphere() ? 4 : 6) + a]) +
               " is not below L in magnitude on the periodic axis " + axis);
    }
  };
  expect_keyword("objects");
  const std::uint64_t count = parse_count(r, f[1], "object count");
  // Room for at most 2^16 objects up front: the count is the file's claim,
  // and a 130-byte file claiming 2^24 objects made the reader take 1.3 GB
  // before it read one (fuzz_scene_reader); beyond, the vectors grow.
  scene.objects.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(count, 1u << 16)));
  scene.velocity.reserve(scene.objects.capacity());
  bool any_filter = false;
  // Version 3's rays block, once its `rays N` line is read.
  bool in_rays = false;
  std::uint64_t ray_count = 0;
  while (r.next(f)) {
    if (f[0] == "rays") {
      if (version < 3) r.fail("a 'rays' block needs 'broadphase-scene 3'");
      if (in_rays) r.fail("a second 'rays' line; a file has one rays block");
      if (scene.objects.size() != count)
        r.fail("the file declares " + std::to_string(count) + " objects but has " +
               std::to_string(scene.objects.size()) + " before its rays block");
      if (f.size() != 2) r.fail("'rays' takes exactly one value");
      ray_count = parse_count(r, f[1], "ray count");
      scene.rays.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(ray_count, 1u << 16)));
      in_rays = true;
      continue;
    }
    if (in_rays) {
      if (f[0] != "ray") r.fail("expected 'ray ...' in the rays block, got " + excerpt(f[0]));
      if (scene.rays.size() == ray_count)
        r.fail("more ray lines than the declared count of " + std::to_string(ray_count));
      scene.rays.push_back(parse_ray(r, f));
      continue;
    }
    if (f[0] == "ray") r.fail("a 'ray' line before its 'rays N' line");
    if (scene.objects.size() == count)
      r.fail("more object lines than the declared count of " + std::to_string(count));
    std::size_t k = 0;
    ShapeKind kind = ShapeKind::sphere;
    if (version >= 2) {
      if (f[0] == "sphere")
        kind = ShapeKind::sphere;
      else if (f[0] == "box")
        kind = ShapeKind::box;
      else
        r.fail("expected 'sphere' or 'box' at the start of an object line, got " + excerpt(f[0]));
      k = 1;
    }
    const std::size_t want = kind == ShapeKind::sphere ? 7 : 9;
    // Version 3: `filter G M` may end the line.
    std::size_t numbers = f.size() - k;
    const bool has_filter = version == 3 && numbers > want && f[k + want] == "filter";
    if (has_filter) {
      if (numbers != want + 3)
        r.fail("'filter' takes exactly two values, the group G and the mask M");
      numbers = want;
    } else if (version < 3 && numbers > want && f[k + want] == "filter") {
      r.fail("'filter' on an object line needs 'broadphase-scene 3'");
    }
    if (numbers != want)
      r.fail("a " + std::string(kind == ShapeKind::sphere ? "sphere" : "box") + " line needs " +
             std::to_string(want) + " numbers, got " + std::to_string(numbers));
    static const char* const kSphereNames[] = {"x", "y", "z", "radius", "vx", "vy", "vz"};
    static const char* const kBoxNames[] = {"x", "y", "z", "hx", "hy", "hz", "vx", "vy", "vz"};
    double v[9];
    for (std::size_t i = 0; i < want; ++i)
      v[i] = r.number(f[k + i], kind == ShapeKind::sphere ? kSphereNames[i] : kBoxNames[i]);
    Filter filter;
    if (has_filter) {
      filter.group = parse_bits(r, f[k + want + 1], "filter group");
      filter.mask = parse_bits(r, f[k + want + 2], "filter mask");
    }
    if (kind == ShapeKind::sphere) {
      if (v[3] < 0) r.fail("radius " + excerpt(f[k + 3]) + " is negative");
      scene.objects.push_back(Shape::sphere({v[0], v[1], v[2]}, v[3]));
      scene.velocity.push_back({v[4], v[5], v[6]});
    } else {
      for (int a = 3; a < 6; ++a)
        if (v[a] < 0) r.fail(std::string(kBoxNames[a]) + " " + excerpt(f[k + a]) + " is negative");
      scene.objects.push_back(Shape::box({v[0], v[1], v[2]}, {v[3], v[4], v[5]}));
      scene.velocity.push_back({v[6], v[7], v[8]});
    }
    if (scene.is_periodic()) check_periodic(scene.objects.back(), scene.velocity.back());
    if (!(filter == Filter{}) && !any_filter) {
      // The first filter that is not the default: every object before it has the default.
      any_filter = true;
      scene.filters.assign(scene.objects.size() - 1, Filter{});
    }
    if (any_filter) scene.filters.push_back(filter);
  }
  if (scene.objects.size() != count)
    throw SceneError(name + ":" + std::to_string(r.line()) + ": the file declares " +
                     std::to_string(count) + " objects but has " +
                     std::to_string(scene.objects.size()));
  if (in_rays && scene.rays.size() != ray_count)
    throw SceneError(name + ":" + std::to_string(r.line()) + ": the file declares " +
                     std::to_string(ray_count) + " rays but has " +
                     std::to_string(scene.rays.size()));
  return scene;
}

Scene read_scene(const std::string& path) {
  // An ifstream opens a directory and then reads nothing: say what it is.
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode))
    throw SceneError(path + ": cannot read: it is a directory, not a scene file");
  std::ifstream in(path);
  if (!in) throw SceneError(path + ": cannot open: " + std::strerror(errno));
  return parse_scene(in, path);
}

namespace {
void put(std::ostream& out, double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  out << buf;
}

void put_bits(std::ostream& out, std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%x", static_cast<unsigned>(v));
  out << buf;
}
}  // namespace

void write_scene(std::ostream& out, const Scene& scene) {
  const int version = scene.version();
  const bool kinds = version >= 2;
  const bool filters = scene.has_filters();
  out << "broadphase-scene " << version << "\nworld ";
  put(out, scene.world);
  if (scene.is_periodic()) out << " periodic " << periodic_axes_text(scene.periodic);
  out << "\nobjects " << scene.objects.size() << "\n";
  out << (version == 3   ? "# sphere x y z r vx vy vz [filter G M] | box x y z hx hy hz vx vy vz "
                           "[filter G M]\n"
          : version == 2 ? "# kind x y z (r | hx hy hz) vx vy vz\n"
                         : "# x y z r vx vy vz\n");
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const Shape& s = scene.objects[i];
    if (kinds) out << (s.kind == ShapeKind::sphere ? "sphere " : "box ");
    put(out, s.center.x), out << ' ', put(out, s.center.y), out << ' ', put(out, s.center.z);
    if (s.kind == ShapeKind::sphere) {
      out << ' ', put(out, s.half.x);
    } else {
      out << ' ', put(out, s.half.x), out << ' ', put(out, s.half.y), out << ' ',
          put(out, s.half.z);
    }
    const Vec3& v = scene.velocity[i];
    out << ' ', put(out, v.x), out << ' ', put(out, v.y), out << ' ', put(out, v.z);
    if (filters && !(scene.filters[i] == Filter{})) {
      out << " filter " << scene.filters[i].group << ' ';
      put_bits(out, scene.filters[i].mask);
    }
    out << '\n';
  }
  if (scene.rays.empty()) return;
  out << "rays " << scene.rays.size() << "\n# ray ox oy oz dx dy dz tmax [filter M]\n";
  for (const Ray& r : scene.rays) {
    out << "ray ";
    put(out, r.origin.x), out << ' ', put(out, r.origin.y), out << ' ', put(out, r.origin.z);
    out << ' ', put(out, r.dir.x), out << ' ', put(out, r.dir.y), out << ' ', put(out, r.dir.z);
    out << ' ';
    if (std::isinf(r.tmax))
      out << "inf";
    else
      put(out, r.tmax);
    if (r.mask != 0xffffffffu) out << " filter ", put_bits(out, r.mask);
    out << '\n';
  }
}

void write_scene(const std::string& path, const Scene& scene) {
  OutputFile out(path);
  write_scene(out.stream(), scene);
  out.commit();
}

void step(Scene& scene) {
  const double L = scene.world;
  if (!scene.is_periodic()) {
    for (std::size_t i = 0; i < scene.objects.size(); ++i) {
      if (!scene.is_moving(i)) continue;
      Vec3& p = scene.objects[i].center;
      Vec3& v = scene.velocity[i];
      step_axis(p.x, v.x, L);
      step_axis(p.y, v.y, L);
      step_axis(p.z, v.z, L);
    }
    return;
  }
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    if (!scene.is_moving(i)) continue;
    Vec3& p = scene.objects[i].center;
    Vec3& v = scene.velocity[i];
    for (int a = 0; a < 3; ++a) {
      if (scene.periodic[a])
        step_axis_periodic(p[a], v[a], L);
      else
        step_axis(p[a], v[a], L);
    }
  }
}

void make_periodic(Scene& scene, const std::array<bool, 3>& axes) {
  const double L = scene.world;
  scene.periodic = axes;
  for (std::size_t i = 0; i < scene.size(); ++i) {
    Shape& s = scene.objects[i];
    Vec3& v = scene.velocity[i];
    for (int a = 0; a < 3; ++a) {
      if (!axes[a]) continue;
      double c = s.center[a] - std::floor(s.center[a] / L) * L;
      if (!(c >= 0 && c < L)) c = 0;  // a rounding of floor to L itself
      s.center[a] = c;
      if (!(std::fabs(v[a]) < L)) v[a] = std::copysign(L / 2, v[a]);
    }
    if (s.is_sphere()) {
      if (!(s.radius() < L / 2)) s = Shape::sphere(s.center, 0.499 * L);
      continue;
    }
    for (int a = 0; a < 3; ++a)
      if (axes[a] && !(s.half[a] < L / 2)) s.half[a] = 0.499 * L;
  }
}

std::string hex16(std::uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

std::uint64_t hit_hash(std::uint32_t ray, std::uint32_t id, double t) {
  std::uint64_t bits = 0;
  std::memcpy(&bits, &t, sizeof bits);
  return splitmix64(splitmix64((std::uint64_t(ray) << 32) | id) + bits);
}

void RayHits::add(std::uint32_t id, double t) {
  if (hits_ == 0 || t < best_t_ || (t == best_t_ && id < best_id_)) {
    best_t_ = t;
    best_id_ = id;
  }
  ++hits_;
  hash_ += hit_hash(ray_, id, t);
}

void RayHits::add_to(HitDigest& d) const {
  d.hits += hits_;
  d.hash += hash_;
  if (hits_ > 0) d.closest += hit_hash(ray_, best_id_, best_t_);
}

std::string frame_line(int frame, const FrameDigest& pairs, const HitDigest* hits) {
  std::string line =
      std::to_string(frame) + ' ' + std::to_string(pairs.pairs) + ' ' + hex16(pairs.hash);
  if (hits)
    line += ' ' + std::to_string(hits->hits) + ' ' + hex16(hits->hash) + ' ' + hex16(hits->closest);
  return line;
}

Distribution parse_distribution(std::string_view name) {
  std::string valid;
  for (Distribution d : kAllDistributions) {
    if (to_string(d) == name) return d;
    valid += (valid.empty() ? "" : ", ") + std::string(to_string(d));
  }
  throw std::invalid_argument("unknown distribution '" + std::string(name) + "'; valid: " + valid);
}

std::string_view to_string(Distribution d) {
  switch (d) {
    case Distribution::even:
      return "even";
    case Distribution::uneven:
      return "uneven";
    case Distribution::scaled_even:
      return "scaled-even";
    case Distribution::scaled_uneven:
      return "scaled-uneven";
    case Distribution::clusters:
      return "clusters";
    case Distribution::decades:
      return "decades";
    case Distribution::all_moving:
      return "all-moving";
    case Distribution::explosion:
      return "explosion";
    case Distribution::flat:
      return "flat";
    case Distribution::coincident:
      return "coincident";
    case Distribution::outside:
      return "outside";
    case Distribution::boxes:
      return "boxes";
    case Distribution::half_boxes:
      return "half-boxes";
    case Distribution::box_decades:
      return "box-decades";
    case Distribution::city:
      return "city";
    case Distribution::shapes_uneven:
      return "shapes-uneven";
    case Distribution::shapes_decades:
      return "shapes-decades";
    case Distribution::shapes_flat:
      return "shapes-flat";
  }
  return "?";
}

Vec3 Rng::direction() {
  // Marsaglia's method: uniform on the sphere without trigonometry.
  for (;;) {
    const double a = uniform(-1, 1), b = uniform(-1, 1);
    const double s = a * a + b * b;
    if (s >= 1 || s == 0) continue;
    const double t = 2 * std::sqrt(1 - s);
    return {a * t, b * t, 1 - 2 * s};
  }
}

namespace {
// Marks k of n indices, chosen uniformly, by a partial Fisher-Yates shuffle.
std::vector<char> choose(std::size_t n, std::size_t k, Rng& rng) {
  std::vector<std::size_t> idx(n);
  std::iota(idx.begin(), idx.end(), std::size_t{0});
  std::vector<char> chosen(n, 0);
  for (std::size_t i = 0; i < k; ++i) {
    std::swap(idx[i], idx[i + rng.below(n - i)]);
    chosen[idx[i]] = 1;
  }
  return chosen;
}
}  // namespace

namespace {

// The study's workloads (docs/scene-format.md).
Scene generate_study(Distribution d, std::size_t n, Rng& rng) {
  Scene s;
  const bool scaled = d == Distribution::scaled_even || d == Distribution::scaled_uneven;
  const bool uneven = d == Distribution::uneven || d == Distribution::scaled_uneven;
  s.world = scaled && n > 0 ? 1000.0 * std::cbrt(static_cast<double>(n) / 6400.0) : 1000.0;
  const double L = s.world;
  const std::vector<char> moving = choose(n, (n * 2 + 5) / 10, rng);            // 20%
  const std::vector<char> low = choose(n, uneven ? (n * 8 + 5) / 10 : 0, rng);  // 80% near ground
  s.objects.reserve(n);
  s.velocity.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double x = rng.uniform(0, L);
    const double y = low[i] ? rng.uniform(0, L / 10) : rng.uniform(0, L);
    const double z = rng.uniform(0, L);
    const double r = rng.uniform(0.5, 50.0);
    s.objects.push_back(Shape::sphere({x, y, z}, r));
    s.velocity.push_back(moving[i] ? rng.direction() * rng.uniform(0.1, 2.0) : Vec3{});
  }
  return s;
}

// A standard normal deviate (Box-Muller).
double gaussian(Rng& rng) {
  const double u = 1.0 - rng.uniform();  // (0, 1]
  return std::sqrt(-2.0 * std::log(u)) * std::cos(6.283185307179586 * rng.uniform());
}

// The stress kinds of the performance work.
Scene generate_stress(Distribution d, std::size_t n, Rng& rng) {
  Scene s;
  s.world = 1000.0;
  const double L = s.world;
  const std::size_t movers =
      d == Distribution::all_moving || d == Distribution::explosion ? n : (n * 2 + 5) / 10;
  const std::vector<char> moving = choose(n, movers, rng);
  const std::size_t clusters = std::max<std::size_t>(1, n / 500);
  std::vector<Vec3> cluster_centre(clusters);
  for (Vec3& c : cluster_centre) c = {rng.uniform(0, L), rng.uniform(0, L), rng.uniform(0, L)};
  std::vector<Vec3> shared_centre(std::max<std::size_t>(1, n / 100));
  for (Vec3& c : shared_centre) c = {rng.uniform(0, L), rng.uniform(0, L), rng.uniform(0, L)};
  const Vec3 mid{L / 2, L / 2, L / 2};
  s.objects.reserve(n);
  s.velocity.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    Vec3 c{rng.uniform(0, L), rng.uniform(0, L), rng.uniform(0, L)};
    double r = rng.uniform(0.5, 5.0);
    Vec3 v = rng.direction() * rng.uniform(0.1, 2.0);
    switch (d) {
      case Distribution::clusters: {
        const Vec3& k = cluster_centre[rng.below(clusters)];
        c = {k.x + gaussian(rng) * L / 40, k.y + gaussian(rng) * L / 40,
             k.z + gaussian(rng) * L / 40};
        break;
      }
      case Distribution::decades:
        r = std::pow(10.0, rng.uniform(-3, 2));
        break;
      case Distribution::explosion: {
        // Debris packed in a ball of radius L/10, flying outwards at up to
        // 20 units a frame in all directions: pairs change wholesale.
        const Vec3 dir = rng.direction();
        c = mid + dir * (L / 10 * std::cbrt(rng.uniform()));
        v = (dir * 0.7 + rng.direction() * 0.3) * rng.uniform(1.0, 20.0);
        break;
      }
      case Distribution::flat:
        c.y = rng.uniform(0, 1);
        break;
      case Distribution::coincident:
        if (rng.uniform() < 0.25) c = shared_centre[rng.below(shared_centre.size())];
        break;
      case Distribution::outside:
        if (rng.uniform() < 0.1) {
          // Outside the cube on at least one axis, up to one world away.
          const int axis = static_cast<int>(rng.below(3));
          c[axis] = rng.uniform() < 0.5 ? rng.uniform(-L, 0) : rng.uniform(L, 2 * L);
          if (rng.uniform() < 0.002) r = rng.uniform(L, 2 * L);
        }
        break;
      default:
        break;
    }
    s.objects.push_back(Shape::sphere(c, r));
    s.velocity.push_back(moving[i] ? v : Vec3{});
  }
  return s;
}

// Half-extents of a box whose largest half side is `s`: cubic, long (one
// side s, the others a tenth of it) or thin (one side a tenth, the others s).
Vec3 box_shape(double s, Rng& rng) {
  const int axis = static_cast<int>(rng.below(3));
  Vec3 h{s, s, s};
  switch (rng.below(3)) {
    case 0:  // cubic
      break;
    case 1:  // long: a beam along `axis`
      h = {s / 10, s / 10, s / 10};
      h[axis] = s;
      break;
    default:  // thin: a plate across `axis`
      h[axis] = s / 10;
  }
  return h;
}

// Log-uniform in [lo, hi].
double log_uniform(double lo, double hi, Rng& rng) { return lo * std::pow(hi / lo, rng.uniform()); }

// Half-extents of a box of the shaped worlds whose sizes are log-uniform
// in [lo, hi]: a pole, a slab (of zero thickness one time in twenty), a
// box of three independent half sides or a cube, a quarter each.
Vec3 shaped_box(double lo, double hi, Rng& rng) {
  const double s = log_uniform(lo, hi, rng);
  const int axis = static_cast<int>(rng.below(3));
  Vec3 h{s, s, s};
  switch (rng.below(4)) {
    case 0:  // pole along `axis`
      for (int a = 0; a < 3; ++a)
        if (a != axis) h[a] = s / log_uniform(10, 100, rng);
      break;
    case 1:  // slab across `axis`
      h[axis] = rng.below(20) == 0 ? 0.0 : s / log_uniform(10, 100, rng);
      break;
    case 2:  // three independent half sides
      h = {log_uniform(lo, hi, rng), log_uniform(lo, hi, rng), log_uniform(lo, hi, rng)};
      break;
    default:  // cube
      break;
  }
  return h;
}

// The shaped worlds (generate()'s comment): half spheres, half boxes of
// every shape, 20% moving.
Scene generate_shaped_world(Distribution d, std::size_t n, Rng& rng) {
  Scene s;
  s.world = 1000.0;
  const double L = s.world;
  const bool decades = d == Distribution::shapes_decades;
  const std::vector<char> moving = choose(n, (n * 2 + 5) / 10, rng);
  const std::vector<char> low =
      choose(n, d == Distribution::shapes_flat ? 0 : (n * 8 + 5) / 10, rng);
  s.objects.reserve(n);
  s.velocity.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    Vec3 c{rng.uniform(0, L), rng.uniform(0, L), rng.uniform(0, L)};
    if (low[i]) c.y = rng.uniform(0, L / 10);
    if (d == Distribution::shapes_flat) c.y = rng.uniform(0, 1);
    Shape shape;
    if (rng.below(2))
      shape = Shape::box(c, decades ? shaped_box(0.01, 100, rng) : shaped_box(0.5, 50, rng));
    else
      shape = Shape::sphere(c, decades ? log_uniform(0.01, 100, rng) : rng.uniform(0.5, 5.0));
    s.objects.push_back(shape);
    s.velocity.push_back(moving[i] ? rng.direction() * rng.uniform(0.1, 2.0) : Vec3{});
  }
  return s;
}

// The box worlds: L = 1000 and the study's speeds, 20% moving, as the
// other stress kinds; the city's movers are its flying spheres.
Scene generate_box_world(Distribution d, std::size_t n, Rng& rng) {
  Scene s;
  s.world = 1000.0;
  const double L = s.world;
  if (d == Distribution::city) {
    // Buildings fill square lots of side 8 on a lattice, each its whole lot,
    // so neighbours touch face to face (dyadic values: exact in any
    // precision); their feet stand on y = 0, the top of the ground box.
    // 70% buildings (one of them the ground), 30% spheres flying above.
    const std::size_t flyers = n < 2 ? 0 : (n * 3 + 5) / 10;
    const std::size_t buildings = n - flyers - (n > 0 ? 1 : 0);
    const auto side =
        static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(buildings))));
    const double extent = 8.0 * static_cast<double>(std::max<std::size_t>(side, 1));
    if (n > 0) {
      s.objects.push_back(
          Shape::box({extent / 2, -0.5, extent / 2}, {extent / 2, 0.5, extent / 2}));
      s.velocity.push_back({});
    }
    for (std::size_t b = 0; b < buildings; ++b) {
      const double half_height = static_cast<double>(1 + rng.below(40));
      const double cx = 8.0 * static_cast<double>(b % side) + 4;
      const double cz = 8.0 * static_cast<double>(b / side) + 4;
      s.objects.push_back(Shape::box({cx, half_height, cz}, {4, half_height, 4}));
      s.velocity.push_back({});
    }
    for (std::size_t f = 0; f < flyers; ++f) {
      const Vec3 c{rng.uniform(0, std::max(L, extent)), rng.uniform(50, L),
                   rng.uniform(0, std::max(L, extent))};
      s.objects.push_back(Shape::sphere(c, rng.uniform(0.5, 5.0)));
      s.velocity.push_back(rng.direction() * rng.uniform(0.1, 2.0));
    }
    return s;
  }
  const std::vector<char> moving = choose(n, (n * 2 + 5) / 10, rng);
  s.objects.reserve(n);
  s.velocity.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 c{rng.uniform(0, L), rng.uniform(0, L), rng.uniform(0, L)};
    Shape shape;
    switch (d) {
      case Distribution::boxes:
        shape = Shape::box(c, box_shape(std::pow(10.0, rng.uniform(-0.6, 1.4)), rng));
        break;
      case Distribution::half_boxes:
        shape = rng.below(2) ? Shape::box(c, box_shape(rng.uniform(0.5, 5.0), rng))
                             : Shape::sphere(c, rng.uniform(0.5, 5.0));
        break;
      default: {  // box_decades
        const double size = std::pow(10.0, rng.uniform(-2, 2));
        shape = rng.below(3) == 0 ? Shape::box(c, box_shape(size, rng)) : Shape::sphere(c, size);
      }
    }
    s.objects.push_back(shape);
    s.velocity.push_back(moving[i] ? rng.direction() * rng.uniform(0.1, 2.0) : Vec3{});
  }
  return s;
}

}  // namespace

Scene generate(Distribution d, std::size_t n, std::uint64_t seed) {
  Rng rng(seed);
  switch (d) {
    case Distribution::even:
    case Distribution::uneven:
    case Distribution::scaled_even:
    case Distribution::scaled_uneven:
      return generate_study(d, n, rng);
    case Distribution::boxes:
    case Distribution::half_boxes:
    case Distribution::box_decades:
    case Distribution::city:
      return generate_box_world(d, n, rng);
    case Distribution::shapes_uneven:
    case Distribution::shapes_decades:
    case Distribution::shapes_flat:
      return generate_shaped_world(d, n, rng);
    default:
      return generate_stress(d, n, rng);
  }
}

}  // namespace broadphase
