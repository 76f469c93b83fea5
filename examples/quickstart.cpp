// The README's example: build a structure, add objects, find pairs, query.
#include <broadphase/broadphase.hpp>
#include <cstdio>

int main() {
  using namespace broadphase;
  auto world = make_structure("naive");  // any name from `broadphase list`
  const Handle a = world->insert(Shape::sphere({0, 0, 0}, 1.0), /*user=*/1);
  const Handle b = world->insert(Shape::sphere({1.5, 0, 0}, 1.0), 2);
  world->insert(Shape::box({10, 0, 0}, {1, 1, 1}), 3, Motion::fixed);

  world->for_each_pair([&](Handle p, Handle q) {
    std::printf("pair %llu-%llu\n", static_cast<unsigned long long>(world->user_data(p)),
                static_cast<unsigned long long>(world->user_data(q)));
    return true;  // keep going
  });
  world->update(b, Shape::sphere({9.5, 0, 0}, 1.0));  // moves next to the box
  const QueryCost cost = world->query(Shape::sphere({10, 0, 0}, 0.5), [&](Handle h) {
    std::printf("touches %llu\n", static_cast<unsigned long long>(world->user_data(h)));
    return true;
  });
  std::printf("%llu narrow-phase tests\n", static_cast<unsigned long long>(cost.tests));
  world->remove(a);
  return world->contains(a) ? 1 : 0;  // the handle is stale now
}
