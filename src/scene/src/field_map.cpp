#include "magvine/scene/field_map.hpp"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <vector>

#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"
#include "magvine/core/units.hpp"
#include "magvine/scene/points_csv.hpp"

namespace magvine::scene {

namespace {

using Vec2 = Eigen::Vector2d;

// Convex hull (Andrew's monotone chain), counter-clockwise.
std::vector<Vec2> convex_hull(std::vector<Vec2> pts) {
  std::sort(pts.begin(), pts.end(),
            [](const Vec2& a, const Vec2& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
  if (pts.size() < 3) return pts;
  auto cross = [](const Vec2& o, const Vec2& a, const Vec2& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  std::vector<Vec2> hull(2 * pts.size());
  std::size_t k = 0;
  for (const auto& p : pts) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], p) <= 0) --k;
    hull[k++] = p;
  }
  for (std::size_t i = pts.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  hull.resize(k - 1);
  return hull;
}

}  // namespace

void write_field_map(const magnetics::FieldModel& model, const FieldMapSpec& spec, const std::filesystem::path& csv,
                     const std::filesystem::path& json) {
  auto axis_index = [&](char c) -> int {
    if (c == 'x') return 0;
    if (c == 'y') return 1;
    if (c == 'z') return 2;
    return -1;
  };
  if (spec.plane.size() != 2 || axis_index(spec.plane[0]) < 0 || axis_index(spec.plane[1]) < 0 ||
      spec.plane[0] == spec.plane[1]) {
    throw InputError("--plane", 0, "", "must be two distinct axes, e.g. xz (got '" + spec.plane + "')");
  }
  if (!(spec.half_width > 0.0) || !std::isfinite(spec.half_width)) throw InputError("--extent", 0, "", "must be > 0");
  if (spec.resolution < 2 || spec.resolution > 4001) throw InputError("--resolution", 0, "", "must be in 2..4001");
  create_output_directory(csv.parent_path());
  const int iu = axis_index(spec.plane[0]);
  const int iv = axis_index(spec.plane[1]);

  const int n = spec.resolution;
  std::vector<Vec3> points;
  points.reserve(static_cast<std::size_t>(n) * n);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      Vec3 p = spec.center;
      p[iu] += -spec.half_width + 2.0 * spec.half_width * i / (n - 1);
      p[iv] += -spec.half_width + 2.0 * spec.half_width * j / (n - 1);
      points.push_back(p);
    }
  }
  std::vector<magnetics::FieldSample> samples(points.size());
  magnetics::field_gradient_batch(model, model.rest_poses, points, samples);

  AtomicFile out_csv(csv);
  out_csv.stream() << "u,v,x,y,z,Bx,By,Bz,B,gradB\n";
  std::string row;
  for (std::size_t k = 0; k < points.size(); ++k) {
    row.clear();
    const Vec3& p = points[k];
    const double values[10] = {p[iu] - spec.center[iu],
                               p[iv] - spec.center[iv],
                               p.x(),
                               p.y(),
                               p.z(),
                               samples[k].b.x(),
                               samples[k].b.y(),
                               samples[k].b.z(),
                               samples[k].b.norm(),
                               samples[k].g.norm()};
    append_csv_row(row, values);
    out_csv.stream() << row;
  }

  nlohmann::json doc;
  doc["plane"] = spec.plane;
  doc["center_m"] = {spec.center.x(), spec.center.y(), spec.center.z()};
  doc["half_width_m"] = spec.half_width;
  doc["resolution"] = n;
  doc["sources"] = nlohmann::json::array();
  for (std::size_t s = 0; s < model.size(); ++s) {
    const magnetics::Pose& pose = model.rest_poses[s];
    nlohmann::json src;
    src["name"] = model.names[s];
    src["position_uv_m"] = {pose.position[iu] - spec.center[iu], pose.position[iv] - spec.center[iv]};
    Vec3 direction = Vec3::Zero();
    std::visit(
        [&](const auto& source) {
          using T = std::decay_t<decltype(source)>;
          if constexpr (std::is_same_v<T, magnetics::CylinderMagnet>) {
            src["kind"] = "cylinder";
            src["diameter_m"] = 2.0 * source.radius();
            src["length_m"] = source.length();
            direction = pose.rotation * source.polarisation();
            std::vector<Vec2> rim;
            constexpr int kRimSamples = 72;
            for (int k = 0; k < kRimSamples; ++k) {
              const double a = 2.0 * kPi * k / kRimSamples;
              for (double zs : {-0.5, 0.5}) {
                const Vec3 local(source.radius() * std::cos(a), source.radius() * std::sin(a), zs * source.length());
                const Vec3 w = pose.rotation * local + pose.position;
                rim.emplace_back(w[iu] - spec.center[iu], w[iv] - spec.center[iv]);
              }
            }
            nlohmann::json outline = nlohmann::json::array();
            for (const auto& q : convex_hull(rim)) outline.push_back({q.x(), q.y()});
            src["outline_uv_m"] = outline;
          } else if constexpr (std::is_same_v<T, magnetics::DipoleSource>) {
            src["kind"] = "dipole";
            direction = pose.rotation * source.moment;
          } else {
            src["kind"] = "uniform";
            direction = pose.rotation * source.b;
          }
        },
        model.sources[s]);
    const Vec2 d2(direction[iu], direction[iv]);
    src["direction_uv"] =
        d2.norm() > 0.0 ? nlohmann::json{d2.x() / d2.norm(), d2.y() / d2.norm()} : nlohmann::json{0.0, 0.0};
    doc["sources"].push_back(src);
  }
  AtomicFile out_json(json);
  out_json.stream() << doc.dump(2) << '\n';
  out_csv.commit();
  out_json.commit();
}

}  // namespace magvine::scene
