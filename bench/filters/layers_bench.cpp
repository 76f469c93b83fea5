// Pair time of a layered world: N objects of a generated scene, each given
// one of L layers (group 1 << layer), its mask its own layer only (`self`)
// or its own and the two neighbouring layers (`near`). One structure holding
// the whole layered world against what it must cost at most: with `self`,
// L structures without filters, one per layer, holding only the pairs that
// pass (the target: the layered world's pair time at most 1.5x
// theirs together); with both, the same world without filters.
//
//   layers_bench KIND N FRAMES LAYERS [self|near] [SPEC]
//   e.g. layers_bench even 6400 100 16 self grid-verlet
//
// Per frame: the scene's movers step, one bulk update per structure, then
// one find_pairs per structure, timed alone (pair time); medians over the
// frames after the first, one thread.
#include <algorithm>
#include <broadphase/broadphase.hpp>
#include <broadphase/detail/median.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

using namespace broadphase;
using Clock = std::chrono::steady_clock;

Distribution parse(const std::string& s) {
  if (s == "even") return Distribution::even;
  if (s == "uneven") return Distribution::uneven;
  if (s == "scaled-even") return Distribution::scaled_even;
  if (s == "scaled-uneven") return Distribution::scaled_uneven;
  std::fprintf(stderr, "layers_bench: KIND is even, uneven, scaled-even or scaled-uneven\n");
  std::exit(2);
}

// A structure and the scene objects it holds (index into the scene).
struct World {
  std::unique_ptr<AnyBroadPhase> s;
  std::vector<std::size_t> objects;
  std::vector<Handle> handles;
  std::vector<HandlePair> pairs;
};

World make(const std::string& spec, const Scene& scene, std::vector<std::size_t> objects,
           const std::vector<Filter>* filters) {
  Config c;
  c.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
  c.expected_objects = objects.size();
  World w{make_structure(spec, c), std::move(objects), {}, {}};
  for (std::size_t i : w.objects)
    w.handles.push_back(w.s->insert(scene.objects[i], i,
                                    scene.is_moving(i) ? Motion::dynamic : Motion::fixed,
                                    filters ? (*filters)[i] : Filter{}));
  w.s->settle();
  return w;
}

void move(World& w, const Scene& scene) {
  std::vector<Move> moves;
  for (std::size_t k = 0; k < w.objects.size(); ++k)
    if (scene.is_moving(w.objects[k])) moves.push_back({w.handles[k], scene.objects[w.objects[k]]});
  w.s->update(moves);
}

double pair_ms(World& w) {
  w.pairs.clear();
  const auto t0 = Clock::now();
  w.s->find_pairs(w.pairs);
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::fprintf(stderr, "usage: layers_bench KIND N FRAMES LAYERS [self|near] [SPEC]\n");
    return 2;
  }
  const Distribution kind = parse(argv[1]);
  const auto n = static_cast<std::size_t>(std::atol(argv[2]));
  const int frames = std::max(2, std::atoi(argv[3]));
  const int layers = std::clamp(std::atoi(argv[4]), 1, 32);
  const bool near = argc > 5 && std::strcmp(argv[5], "near") == 0;
  const std::string spec = argc > 6 ? argv[6] : "grid-verlet";
  Scene scene = generate(kind, n, 1);
  std::vector<Filter> filters(scene.size());
  std::vector<std::vector<std::size_t>> by_layer(static_cast<std::size_t>(layers));
  Rng rng(7);
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const auto l = static_cast<std::uint32_t>(rng.below(static_cast<std::uint64_t>(layers)));
    const auto L = static_cast<std::uint32_t>(layers);
    std::uint32_t mask = 1u << l;
    if (near) mask |= (1u << ((l + 1) % L)) | (1u << ((l + L - 1) % L));
    filters[i] = {1u << l, mask};
    by_layer[l].push_back(i);
  }
  std::vector<std::size_t> all(scene.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
  World layered = make(spec, scene, all, &filters);
  World plain = make(spec, scene, all, nullptr);
  std::vector<World> apart;
  if (!near)
    for (auto& objects : by_layer) apart.push_back(make(spec, scene, objects, nullptr));
  std::vector<double> t_layered, t_plain, t_apart;
  std::size_t p_layered = 0, p_plain = 0, p_apart = 0;
  for (int f = 0; f < frames; ++f) {
    step(scene);
    move(layered, scene);
    move(plain, scene);
    for (World& w : apart) move(w, scene);
    // Interleaved, so that the host's drift falls on all alike.
    const double a = pair_ms(layered);
    const double b = pair_ms(plain);
    double c = 0;
    std::size_t pc = 0;
    for (World& w : apart) {
      c += pair_ms(w);
      pc += w.pairs.size();
    }
    if (!near && layered.pairs.size() != pc) {
      std::fprintf(stderr, "frame %d: the layered world has %zu pairs, its layers %zu\n", f,
                   layered.pairs.size(), pc);
      return 1;
    }
    if (f == 0) continue;
    t_layered.push_back(a);
    t_plain.push_back(b);
    t_apart.push_back(c);
    p_layered += layered.pairs.size();
    p_plain += plain.pairs.size();
    p_apart += pc;
  }
  const double fl = static_cast<double>(frames - 1);
  const double ml = detail::median(t_layered), mp = detail::median(t_plain);
  std::printf("%s %s n=%zu layers=%d mask=%s frames=%d\n", spec.c_str(), argv[1], scene.size(),
              layers, near ? "near" : "self", frames);
  std::printf("  layered world:    %8.3f ms  %10.1f pairs\n", ml,
              static_cast<double>(p_layered) / fl);
  std::printf("  without filters:  %8.3f ms  %10.1f pairs   layered/unfiltered %.2f\n", mp,
              static_cast<double>(p_plain) / fl, ml / mp);
  if (!near) {
    const double ma = detail::median(t_apart);
    std::printf("  %2d worlds apart:  %8.3f ms  %10.1f pairs   layered/apart %.2f\n", layers, ma,
                static_cast<double>(p_apart) / fl, ml / ma);
  }
  return 0;
}
