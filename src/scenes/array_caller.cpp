#include <broadphase/scenes/array_caller.hpp>
#include <cmath>
#include <cstdint>

namespace broadphase {

ArrayCaller::ArrayCaller(const Scene& scene)
    : world_(scene.world), boxes_(scene.has_boxes()), periodic_(scene.periodic) {
  const std::size_t n = scene.size();
  for (auto* v : {&x_, &y_, &z_, &hx_}) v->resize(n);
  if (boxes_) {
    hy_.resize(n);
    hz_.resize(n);
    kind_.resize(n);
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Shape& s = scene.objects[i];
    x_[i] = s.center.x, y_[i] = s.center.y, z_[i] = s.center.z;
    hx_[i] = s.half.x;
    if (boxes_) {
      hy_[i] = s.half.y, hz_[i] = s.half.z;
      kind_[i] = s.is_sphere() ? 0 : 1;
    }
    if (scene.is_moving(i)) movers_.push_back(static_cast<std::uint32_t>(i));
  }
  if (scene.has_filters()) {
    groups_.reserve(n);
    masks_.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      groups_.push_back(scene.filter(i).group);
      masks_.push_back(scene.filter(i).mask);
    }
  }
  // Only the movers' velocities are kept, in the movers' order.
  for (auto* v : {&vx_, &vy_, &vz_}) v->reserve(movers_.size());
  for (std::uint32_t i : movers_) {
    vx_.push_back(scene.velocity[i].x);
    vy_.push_back(scene.velocity[i].y);
    vz_.push_back(scene.velocity[i].z);
  }
}

Objects ArrayCaller::objects() const {
  Objects o;
  o.count = x_.size();
  o.x = Column::of(x_.data());
  o.y = Column::of(y_.data());
  o.z = Column::of(z_.data());
  o.radius = Column::of(hx_.data());  // a sphere's radius is its half.x
  if (boxes_) {
    o.half_x = Column::of(hx_.data());
    o.half_y = Column::of(hy_.data());
    o.half_z = Column::of(hz_.data());
    o.kind = kind_.data();
  }
  o.groups = groups_;
  o.masks = masks_;
  return o;
}

std::size_t ArrayCaller::step() {
  std::size_t bad = SIZE_MAX;
  for (std::size_t m = 0; m < movers_.size(); ++m) {
    const std::uint32_t i = movers_[m];
    // The axes in the contract's order, each reflecting or wrapping.
    double* p[3] = {&x_[i], &y_[i], &z_[i]};
    double* v[3] = {&vx_[m], &vy_[m], &vz_[m]};
    for (std::size_t a = 0; a < 3; ++a) {
      if (periodic_[a])
        step_axis_periodic(*p[a], *v[a], world_);
      else
        step_axis(*p[a], *v[a], world_);
    }
    if (bad == SIZE_MAX && !(std::isfinite(x_[i]) && std::isfinite(y_[i]) && std::isfinite(z_[i])))
      bad = i;
  }
  return bad;
}

std::size_t ArrayCaller::bytes() const {
  return x_.size() * (boxes_ ? 6 * sizeof(double) + 1 : 4 * sizeof(double)) +
         (groups_.size() + masks_.size()) * sizeof(std::uint32_t);
}

}  // namespace broadphase
