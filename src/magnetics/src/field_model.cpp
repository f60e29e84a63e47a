#include "magvine/magnetics/field_model.hpp"

#include "magvine/core/check.hpp"
#include "magvine/magnetics/dipole.hpp"

namespace magvine::magnetics {

namespace {

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};

// Adds the contribution of one posed source to out[i] for every point. Dipoles and uniform fields are
// evaluated directly in the world frame (their moment/field rotated once); cylinders in their local frame.
template <bool kWithGradient, class Out>
void accumulate(const FieldSource& source, const Pose& pose, std::span<const Vec3> points, std::span<Out> out) {
  std::visit(Overloaded{
                 [&](const UniformSource& u) {
                   const Vec3 b = pose.rotation * u.b;
                   for (std::size_t i = 0; i < points.size(); ++i) {
                     if constexpr (kWithGradient) out[i].b += b;
                     else out[i] += b;
                   }
                 },
                 [&](const DipoleSource& d) {
                   const Vec3 m = pose.rotation * d.moment;
                   for (std::size_t i = 0; i < points.size(); ++i) {
                     if constexpr (kWithGradient) out[i] += dipole_field_gradient(m, points[i] - pose.position);
                     else out[i] += dipole_field(m, points[i] - pose.position);
                   }
                 },
                 [&](const CylinderMagnet& c) {
                   const Mat3& r = pose.rotation;
                   for (std::size_t i = 0; i < points.size(); ++i) {
                     const Vec3 p = pose.to_local(points[i]);
                     if constexpr (kWithGradient) {
                       const FieldSample s = c.field_gradient(p);
                       out[i].b += r * s.b;
                       out[i].g += r * s.g * r.transpose();
                     } else {
                       out[i] += r * c.field(p);
                     }
                   }
                 },
             },
             source);
}

}  // namespace

void FieldModel::add(FieldSource source, const Pose& pose, std::string name) {
  sources.push_back(std::move(source));
  rest_poses.push_back(pose);
  names.push_back(std::move(name));
}

bool FieldModel::has_gradient() const {
  for (const auto& s : sources) {
    if (!std::holds_alternative<UniformSource>(s)) return true;
  }
  return false;
}

bool FieldModel::has_analytic_curvature() const {
  for (const auto& s : sources) {
    if (!std::holds_alternative<UniformSource>(s) && !std::holds_alternative<DipoleSource>(s)) return false;
  }
  return true;
}

Mat3 field_curvature(const FieldModel& model, std::span<const Pose> poses, const Vec3& x, const Vec3& w) {
  MAGVINE_ASSERT(poses.size() == model.size() && model.has_analytic_curvature());
  Mat3 out = Mat3::Zero();
  for (std::size_t k = 0; k < model.size(); ++k) {
    if (const auto* d = std::get_if<DipoleSource>(&model.sources[k])) {
      out += dipole_field_curvature(poses[k].rotation * d->moment, x - poses[k].position, w);
    }
  }
  return out;
}

void field_batch(const FieldModel& model, std::span<const Pose> poses, std::span<const Vec3> points,
                 std::span<Vec3> out) {
  MAGVINE_ASSERT(poses.size() == model.size() && out.size() == points.size());
  for (auto& o : out) o.setZero();
  for (std::size_t k = 0; k < model.size(); ++k) accumulate<false>(model.sources[k], poses[k], points, out);
}

void field_gradient_batch(const FieldModel& model, std::span<const Pose> poses, std::span<const Vec3> points,
                          std::span<FieldSample> out) {
  MAGVINE_ASSERT(poses.size() == model.size() && out.size() == points.size());
  for (auto& o : out) o = FieldSample{};
  for (std::size_t k = 0; k < model.size(); ++k) accumulate<true>(model.sources[k], poses[k], points, out);
}

Vec3 field(const FieldModel& model, std::span<const Pose> poses, const Vec3& x) {
  Vec3 out;
  field_batch(model, poses, std::span<const Vec3>(&x, 1), std::span<Vec3>(&out, 1));
  return out;
}

FieldSample field_gradient(const FieldModel& model, std::span<const Pose> poses, const Vec3& x) {
  FieldSample out;
  field_gradient_batch(model, poses, std::span<const Vec3>(&x, 1), std::span<FieldSample>(&out, 1));
  return out;
}

}  // namespace magvine::magnetics
