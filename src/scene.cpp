#include <broadphase/scene.hpp>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <numeric>
#include <sstream>

namespace broadphase {

bool Scene::has_boxes() const {
  for (const Shape& s : objects)
    if (s.kind == ShapeKind::box) return true;
  return false;
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
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
    if (ec == std::errc::result_out_of_range)
      fail(std::string(what) + " '" + std::string(text) + "' is out of the range of a double");
    if (ec != std::errc{} || end != text.data() + text.size())
      fail(std::string(what) + " '" + std::string(text) + "' is not a number");
    if (!std::isfinite(v)) fail(std::string(what) + " is " + std::string(text) + ", not finite");
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

Scene parse_scene(std::istream& in, const std::string& name) {
  LineReader r(in, name);
  std::vector<std::string_view> f;
  std::string header;
  // The header must be line 1 exactly, so it is read raw, not skipped as blank.
  if (!r.raw(header)) r.fail("empty file; expected 'broadphase-scene 1' or 'broadphase-scene 2'");
  if (!header.empty() && header.back() == '\r') header.pop_back();
  int version = 0;
  if (header == "broadphase-scene 1") version = 1;
  else if (header == "broadphase-scene 2") version = 2;
  else r.fail("expected 'broadphase-scene 1' or 'broadphase-scene 2', got '" + header + "'");
  Scene scene;
  auto expect_keyword = [&](const char* key) {
    if (!r.next(f)) r.fail(std::string("missing '") + key + " ...' line");
    if (f[0] != key) r.fail(std::string("expected '") + key + " ...', got '" + std::string(f[0]) + "'");
    if (f.size() != 2) r.fail(std::string("'") + key + "' takes exactly one value");
  };
  expect_keyword("world");
  scene.world = r.number(f[1], "world size");
  if (!(scene.world > 0)) r.fail("world size must be > 0");
  expect_keyword("objects");
  std::uint64_t count = 0;
  {
    const auto [end, ec] = std::from_chars(f[1].data(), f[1].data() + f[1].size(), count);
    if (ec != std::errc{} || end != f[1].data() + f[1].size() || count > 0xfffffffeull)
      r.fail("object count '" + std::string(f[1]) + "' is not a whole number below 2^32");
  }
  scene.objects.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(count, 1u << 24)));
  scene.velocity.reserve(scene.objects.capacity());
  while (r.next(f)) {
    if (scene.objects.size() == count)
      r.fail("more object lines than the declared count of " + std::to_string(count));
    std::size_t k = 0;
    ShapeKind kind = ShapeKind::sphere;
    if (version == 2) {
      if (f[0] == "sphere") kind = ShapeKind::sphere;
      else if (f[0] == "box") kind = ShapeKind::box;
      else r.fail("expected 'sphere' or 'box' at the start of an object line, got '" + std::string(f[0]) + "'");
      k = 1;
    }
    const std::size_t want = kind == ShapeKind::sphere ? 7 : 9;
    if (f.size() - k != want)
      r.fail("a " + std::string(kind == ShapeKind::sphere ? "sphere" : "box") + " line needs " +
             std::to_string(want) + " numbers, got " + std::to_string(f.size() - k));
    static const char* const kSphereNames[] = {"x", "y", "z", "radius", "vx", "vy", "vz"};
    static const char* const kBoxNames[] = {"x", "y", "z", "hx", "hy", "hz", "vx", "vy", "vz"};
    double v[9];
    for (std::size_t i = 0; i < want; ++i)
      v[i] = r.number(f[k + i], kind == ShapeKind::sphere ? kSphereNames[i] : kBoxNames[i]);
    if (kind == ShapeKind::sphere) {
      if (v[3] < 0) r.fail("radius " + std::string(f[k + 3]) + " is negative");
      scene.objects.push_back(Shape::sphere({v[0], v[1], v[2]}, v[3]));
      scene.velocity.push_back({v[4], v[5], v[6]});
    } else {
      for (int a = 3; a < 6; ++a)
        if (v[a] < 0) r.fail(std::string(kBoxNames[a]) + " " + std::string(f[k + a]) + " is negative");
      scene.objects.push_back(Shape::box({v[0], v[1], v[2]}, {v[3], v[4], v[5]}));
      scene.velocity.push_back({v[6], v[7], v[8]});
    }
  }
  if (scene.objects.size() != count)
    throw SceneError(name + ":" + std::to_string(r.line()) + ": the file declares " +
                     std::to_string(count) + " objects but has " +
                     std::to_string(scene.objects.size()));
  return scene;
}

Scene read_scene(const std::string& path) {
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
}  // namespace

void write_scene(std::ostream& out, const Scene& scene) {
  const bool v2 = scene.has_boxes();
  out << "broadphase-scene " << (v2 ? 2 : 1) << "\nworld ";
  put(out, scene.world);
  out << "\nobjects " << scene.objects.size() << "\n";
  out << (v2 ? "# kind x y z (r | hx hy hz) vx vy vz\n" : "# x y z r vx vy vz\n");
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const Shape& s = scene.objects[i];
    if (v2) out << (s.kind == ShapeKind::sphere ? "sphere " : "box ");
    put(out, s.center.x), out << ' ', put(out, s.center.y), out << ' ', put(out, s.center.z);
    if (s.kind == ShapeKind::sphere) {
      out << ' ', put(out, s.half.x);
    } else {
      out << ' ', put(out, s.half.x), out << ' ', put(out, s.half.y), out << ' ', put(out, s.half.z);
    }
    const Vec3& v = scene.velocity[i];
    out << ' ', put(out, v.x), out << ' ', put(out, v.y), out << ' ', put(out, v.z);
    out << '\n';
  }
}

void write_scene(const std::string& path, const Scene& scene) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot write: " + std::strerror(errno));
  write_scene(out, scene);
  out.flush();
  if (!out) throw std::runtime_error(path + ": write failed");
}

void step(Scene& scene) {
  const double L = scene.world;
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    if (!scene.is_moving(i)) continue;
    Vec3& p = scene.objects[i].center;
    Vec3& v = scene.velocity[i];
    step_axis(p.x, v.x, L);
    step_axis(p.y, v.y, L);
    step_axis(p.z, v.z, L);
  }
}

std::string hex16(std::uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

Distribution parse_distribution(std::string_view name) {
  if (name == "even") return Distribution::even;
  if (name == "uneven") return Distribution::uneven;
  if (name == "scaled-even") return Distribution::scaled_even;
  if (name == "scaled-uneven") return Distribution::scaled_uneven;
  throw std::invalid_argument("unknown distribution '" + std::string(name) +
                              "'; valid: even, uneven, scaled-even, scaled-uneven");
}

std::string_view to_string(Distribution d) {
  switch (d) {
    case Distribution::even: return "even";
    case Distribution::uneven: return "uneven";
    case Distribution::scaled_even: return "scaled-even";
    case Distribution::scaled_uneven: return "scaled-uneven";
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

Scene generate(Distribution d, std::size_t n, std::uint64_t seed) {
  Rng rng(seed);
  Scene s;
  const bool scaled = d == Distribution::scaled_even || d == Distribution::scaled_uneven;
  const bool uneven = d == Distribution::uneven || d == Distribution::scaled_uneven;
  s.world = scaled ? 1000.0 * std::cbrt(static_cast<double>(n) / 6400.0) : 1000.0;
  if (!(s.world > 0)) s.world = 1000.0;
  const double L = s.world;
  const std::vector<char> moving = choose(n, (n * 2 + 5) / 10, rng);          // 20%
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

}  // namespace broadphase
