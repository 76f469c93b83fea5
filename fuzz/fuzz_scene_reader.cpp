// Fuzzes the scene reader (lab/scene.hpp): any bytes either parse or throw
// SceneError, never crash or hang; a scene that parses is written and read
// back to the same doubles, filters and rays (the format's exact round
// trip), and names its objects' shapes and its rays validly.
#include <broadphase/scenes/scene.hpp>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>

namespace {

bool same(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0 || (a == 0 && b == 0); }
bool same(const broadphase::Vec3& a, const broadphase::Vec3& b) {
  return same(a.x, b.x) && same(a.y, b.y) && same(a.z, b.z);
}

[[noreturn]] void finding(const char* what) {
  std::fprintf(stderr, "FINDING: %s\n", what);
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace broadphase;
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  Scene scene;
  try {
    scene = parse_scene(in, "fuzz");
  } catch (const SceneError&) {
    return 0;  // refused, with a message: fine
  }
  if (scene.objects.size() != scene.velocity.size())
    finding("objects and velocities differ in count");
  for (const Shape& s : scene.objects)
    if (!is_valid(s)) finding("a parsed shape is not valid");
  if (!scene.filters.empty() && scene.filters.size() != scene.objects.size())
    finding("filters and objects differ in count");
  for (const Ray& r : scene.rays)
    if (!is_valid(r)) finding("a parsed ray is not valid");
  std::ostringstream out;
  write_scene(out, scene);
  std::istringstream back_in(out.str());
  Scene back;
  try {
    back = parse_scene(back_in, "round trip");
  } catch (const SceneError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    finding("a written scene does not read back");
  }
  if (!same(back.world, scene.world) || back.objects.size() != scene.objects.size())
    finding("round trip changed the world or the count");
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const Shape& a = scene.objects[i];
    const Shape& b = back.objects[i];
    if (a.kind != b.kind || !same(a.center, b.center) || !same(a.half, b.half) ||
        !same(scene.velocity[i], back.velocity[i]))
      finding("round trip changed an object");
    if (!(scene.filter(i) == back.filter(i))) finding("round trip changed a filter");
  }
  if (back.rays.size() != scene.rays.size()) finding("round trip changed the ray count");
  for (std::size_t k = 0; k < scene.rays.size(); ++k) {
    const Ray& a = scene.rays[k];
    const Ray& b = back.rays[k];
    if (!same(a.origin, b.origin) || !same(a.dir, b.dir) || !same(a.tmax, b.tmax) ||
        a.mask != b.mask)
      finding("round trip changed a ray");
  }
  return 0;
}
