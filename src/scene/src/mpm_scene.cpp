#include "magvine/scene/mpm_scene.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "failed_run.hpp"
#include "magnet_entries.hpp"
#include "magvine/anatomy/collision_world.hpp"
#include "magvine/anatomy/mesh_io.hpp"
#include "magvine/core/atomic_file.hpp"
#include "magvine/core/error.hpp"
#include "magvine/core/stopwatch.hpp"
#include "magvine/core/units.hpp"
#include "magvine/core/usage.hpp"
#include "magvine/mpm/cantilever.hpp"
#include "magvine/mpm/sampling.hpp"
#include "magvine/mpm/total_lagrangian.hpp"
#include "magvine/robot/elastica.hpp"
#include "magvine/scene/video_plugin.hpp"
#include "ranges.hpp"
#include "robot_entries.hpp"
#include "yaml_reader.hpp"

namespace magvine::scene {
namespace {

constexpr double kDefaultImplicitRatio = 10.0;  // the implicit step's default: 10 explicit steps (docs/scenes.md)
constexpr double kDefaultCourant = 0.4;  // of the P-wave CFL step; stable in every test and scene (docs/mpm.md)
constexpr int kDefaultParticlesPerCell = 2;
constexpr double kDefaultBulkRatio = 20.0;  // K = 20 G (thesis eq 3.10)
constexpr double kMaxParticles = 2e7;
constexpr double kMaxNodes = 2e8;  // grid nodes of the domain's bounding box at δx: a typo in cell is refused early

mpm::Boundary boundary_of(const YamlMap& m, const std::string& key) {
  const std::string b = m.text(key);
  if (b == "sticky") return mpm::Boundary::kSticky;
  if (b == "slip") return mpm::Boundary::kSlip;
  if (b == "friction") return mpm::Boundary::kFriction;
  m.fail(key, "must be sticky, slip or friction (got '" + b + "')");
}

double friction_of(const YamlMap& m, mpm::Boundary b) {
  if (!m.has("friction")) {
    if (b == mpm::Boundary::kFriction) m.fail("friction", "missing required key (boundary: friction needs μ)");
    return 0.0;
  }
  return m.quantity("friction", kPlain, range::kFriction);
}

mpm::Material material_of(const YamlMap& m, const Unit& stress) {
  m.allow_only({"shear_modulus", "bulk_modulus", "density"});
  mpm::Material mat;
  mat.shear_modulus = m.quantity("shear_modulus", stress, range::kModulus);
  mat.bulk_modulus = m.has("bulk_modulus") ? m.quantity("bulk_modulus", stress, range::kModulus)
                                           : kDefaultBulkRatio * mat.shear_modulus;
  mat.density = m.quantity("density", kKgPerM3, Range{0.0, range::kDensity.max, true});
  return mat;
}

/// Remanence B̃r [T] from {remanence, direction}.
Vec3 remanence_of(const YamlMap& m) {
  m.allow_only({"remanence", "direction", "axis", "from", "to"});
  return m.quantity("remanence", kTesla, range::kRemanence) * m.direction("direction");
}

int axis_of(const YamlMap& m) {
  const std::string a = m.text("axis");
  if (a == "x") return 0;
  if (a == "y") return 1;
  if (a == "z") return 2;
  m.fail("axis", "must be x, y or z (got '" + a + "')");
}

MpmFieldSchedule field_of(const YamlMap& f) {
  f.allow_only({"b", "keyframes", "rotating"});
  const int kinds =
      static_cast<int>(f.has("b")) + static_cast<int>(f.has("keyframes")) + static_cast<int>(f.has("rotating"));
  // keyframes and a rotation go together when the rotation says when it takes over (`from`).
  const bool ramp_then_rotation =
      kinds == 2 && f.has("keyframes") && f.has("rotating") && f.map("rotating").has("from");
  if (kinds != 1 && !ramp_then_rotation)
    f.fail("b", "give exactly one of b (constant), keyframes or rotating (or keyframes and a rotating with from)");
  MpmFieldSchedule s;
  if (f.has("b")) s.keyframes.push_back({0.0, f.vec3_quantity("b", kTesla, range::kField)});
  if (f.has("keyframes")) {
    const YAML::Node list = f.node("keyframes");
    if (!list.IsSequence() || list.size() == 0) f.fail("keyframes", "must be a list of {t, b}");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const YamlMap k(list[i], f.file(), f.key_path("keyframes[" + std::to_string(i) + "]"));
      k.allow_only({"t", "b"});
      const double t = k.quantity("t", kSeconds, range::kTime);
      if (!s.keyframes.empty() && t <= s.keyframes.back().first) k.fail("t", "must increase from keyframe to keyframe");
      s.keyframes.push_back({t, k.vec3_quantity("b", kTesla, range::kField)});
    }
  }
  if (f.has("rotating")) {
    const YamlMap r = f.map("rotating");
    r.allow_only({"amplitude", "frequency", "axis", "start", "from"});
    s.rotating = true;
    if (r.has("from")) {
      s.rotation_start = r.quantity("from", kSeconds, range::kTime);
      if (!s.keyframes.empty() && s.rotation_start < s.keyframes.back().first)
        r.fail("from", "must not come before the last keyframe");
    }
    s.amplitude = r.quantity("amplitude", kTesla, range::kField);
    s.frequency = r.quantity("frequency", Unit{1.0, "Hz"}, Range{-1e6, 1e6});
    s.axis = r.direction("axis");
    Vec3 start = r.direction("start");
    start -= start.dot(s.axis) * s.axis;
    if (start.norm() < 1e-9) r.fail("start", "must not be parallel to " + r.key_path("axis"));
    s.start = start.normalized();
  }
  return s;
}

/// The mesh a body or obstacle names in `file` (relative to the scene's folder, in the file's length unit) [m] and
/// its path; one that cannot be read fails at the entry's `file`.
std::pair<anatomy::TriangleMesh, std::filesystem::path> entry_mesh(const YamlMap& m, const Unit& unit,
                                                                   const std::filesystem::path& base_dir) {
  std::filesystem::path file = m.text("file");
  if (file.is_relative()) file = base_dir / file;
  anatomy::MeshImportOptions options;
  options.scale = unit.si;
  options.units = LengthUnit::kM;
  try {
    return {anatomy::import_mesh(file, options).mesh, file};
  } catch (const InputError& e) {
    m.fail("file", e.what());
  }
}

/// A mesh's signed distance for an MPM obstacle (docs/mpm.md#meshes-as-boundaries): the unsigned distance to the
/// nearest triangle (CollisionWorld::triangles_within, exact), signed by which side of the surface the point lies
/// on: for a closed mesh by ray parity (CollisionWorld::contains), for an open one (a floor, a wall) by the nearest
/// triangle's outward normal. `container`: the body lives inside the closed mesh (an airway's lumen) and the solid is
/// outside; otherwise the mesh is the solid. Points farther than `band` from the surface get ±band (their distance
/// does not matter, only the side), except in the solid, where the search widens until it finds the surface (the
/// normal that pushes a node back out).
class MeshDistance final : public mpm::SignedDistance {
 public:
  MeshDistance(const anatomy::TriangleMesh& mesh, bool container, double band)
      : m_world(mesh), m_container(container), m_band(band) {
    m_closed = m_world.stats().boundary_edges == 0;
    anatomy::Aabb box{mesh.vertices.front(), mesh.vertices.front()};
    for (const Vec3& v : mesh.vertices) {
      box.min = box.min.cwiseMin(v);
      box.max = box.max.cwiseMax(v);
    }
    m_reach = 2.0 * (box.max - box.min).norm() + band;
  }

  bool closed() const { return m_closed; }

  double at(const Vec3& x, Vec3* normal) const override {
    anatomy::NearTriangle near[1];
    std::size_t found = m_world.triangles_within(x, m_band, near);
    const bool in_volume = m_closed ? m_world.contains(x) : false;
    if (found == 0) {
      const bool free = m_closed ? (in_volume == m_container) : true;  // an open mesh: nothing near, nothing to meet
      if (free) {
        *normal = Vec3::UnitZ();
        return m_band;
      }
      for (double r = 4.0 * m_band; found == 0 && r < 4.0 * m_reach; r *= 4.0)
        found = m_world.triangles_within(x, r, near);
      if (found == 0) {
        *normal = Vec3::UnitZ();
        return -m_reach;
      }
    }
    const anatomy::TriangleMesh& mesh = m_world.mesh();
    const std::size_t t = near[0].triangle;
    const Vec3 outward = (anatomy::corner(mesh, t, 1) - anatomy::corner(mesh, t, 0))
                             .cross(anatomy::corner(mesh, t, 2) - anatomy::corner(mesh, t, 0))
                             .normalized();
    const Vec3 off = x - near[0].point;
    const bool inside = m_closed ? in_volume : off.dot(outward) < 0.0;
    const bool free = inside == m_container;
    const double d = near[0].distance;
    // Out of the solid: away from the wall on the free side, back toward it in the solid; on the surface, the face's.
    if (d > 1e-12 * m_reach) {
      *normal = (free ? 1.0 : -1.0) * off / d;
    } else {
      *normal = m_container ? Vec3(-outward) : outward;
    }
    return free ? std::min(d, m_band) : -d;
  }

 private:
  anatomy::CollisionWorld m_world;
  bool m_container;
  double m_band;
  double m_reach = 0.0;
  bool m_closed = false;
};

mpm::Obstacle obstacle_of(const YamlMap& o, const Unit& unit, int dim, double cell,
                          const std::filesystem::path& base_dir) {
  o.allow_only({"name", "shape", "min", "max", "centre", "radius", "point", "normal", "from", "to", "file", "side",
                "boundary", "friction"});
  mpm::Obstacle ob;
  ob.name = o.has("name") ? o.text("name") : o.path();
  const std::string shape = o.text("shape");
  if (shape == "box") {
    ob.shape = mpm::Obstacle::Shape::kBox;
    ob.a = o.vec3_quantity("min", unit, range::kCoordinate);
    ob.b = o.vec3_quantity("max", unit, range::kCoordinate);
    if ((ob.b.array() <= ob.a.array()).any()) o.fail("max", "must exceed min on every axis");
  } else if (shape == "sphere") {
    ob.shape = mpm::Obstacle::Shape::kSphere;
    ob.a = o.vec3_quantity("centre", unit, range::kCoordinate);
    ob.radius = o.quantity("radius", unit, range::kDistance);
  } else if (shape == "plane") {
    ob.shape = mpm::Obstacle::Shape::kHalfSpace;
    ob.a = o.vec3_quantity("point", unit, range::kCoordinate);
    ob.b = o.direction("normal");
  } else if (shape == "cylinder") {
    ob.shape = mpm::Obstacle::Shape::kCylinder;
    ob.a = o.vec3_quantity("from", unit, range::kCoordinate);
    ob.b = o.vec3_quantity("to", unit, range::kCoordinate);
    ob.radius = o.quantity("radius", unit, range::kDistance);
    if ((ob.b - ob.a).norm() <= 0.0) o.fail("to", "must differ from from");
  } else if (shape == "mesh") {
    if (dim == 2) o.fail("shape", "a mesh obstacle needs dimension: 3");
    if (!o.has("file")) o.fail("file", "missing required key (a mesh obstacle names its mesh)");
    const bool container =
        o.has("side") ? o.choice<bool>("side", {"inside", true}, {"outside", false}) : false;  // the mesh is the solid
    const auto [mesh, file] = entry_mesh(o, unit, base_dir);
    auto distance = std::make_shared<const MeshDistance>(mesh, container, 2.0 * cell);
    if (container && !distance->closed()) {
      o.fail("side", "inside needs a closed mesh (" + file.string() + " has open edges): the inside of what?");
    }
    ob.shape = mpm::Obstacle::Shape::kSampled;
    ob.sampled = distance;
  } else {
    o.fail("shape", "must be box, sphere, plane, cylinder or mesh (got '" + shape + "')");
  }
  if (shape != "mesh") {
    for (const char* key : {"file", "side"}) {
      if (o.has(key)) o.fail(key, "is for shape: mesh only");
    }
  }
  ob.boundary = o.has("boundary") ? boundary_of(o, "boundary") : mpm::Boundary::kSticky;
  ob.friction = friction_of(o, ob.boundary);
  return ob;
}

/// Particles of one body: positions, per-particle remanence, and the lattice spacing.
struct BodyParticles {
  std::vector<Vec3> x;
  std::vector<Vec3> br;
  mpm::Material material;
  std::string name;
};

BodyParticles body_of(const YamlMap& b, const FileUnits& units, const mpm::LatticeOptions& lattice, int dim,
                      const std::filesystem::path& base_dir) {
  b.allow_only(
      {"name", "shape", "min", "max", "from", "to", "radius", "file", "material", "magnetisation", "sections"});
  BodyParticles out;
  out.name = b.has("name") ? b.text("name") : b.path();
  out.material = material_of(b.map("material"), units.stress);
  const Unit& unit = units.len;
  const std::string shape = b.text("shape");
  if (shape == "box") {
    const Vec3 lo = b.vec3_quantity("min", unit, range::kCoordinate);
    const Vec3 hi = b.vec3_quantity("max", unit, range::kCoordinate);
    for (int a = 0; a < dim; ++a) {
      if (hi[a] <= lo[a]) b.fail("max", "must exceed min on every axis of the simulation");
    }
    out.x = mpm::sample_box(lo, hi, lattice, dim);
  } else if (shape == "cylinder") {
    if (dim == 2) b.fail("shape", "a cylinder needs dimension: 3");
    out.x = mpm::sample_cylinder(b.vec3_quantity("from", unit, range::kCoordinate),
                                 b.vec3_quantity("to", unit, range::kCoordinate),
                                 b.quantity("radius", unit, range::kDistance), lattice);
  } else if (shape == "mesh") {
    if (dim == 2) b.fail("shape", "a mesh needs dimension: 3");
    const auto [mesh, file] = entry_mesh(b, unit, base_dir);
    try {
      out.x = mpm::sample_mesh(mesh, lattice, file.string());
    } catch (const InputError& e) {
      b.fail("file", e.what());
    }
  } else {
    b.fail("shape", "must be box, cylinder or mesh (got '" + shape + "')");
  }
  if (out.x.empty()) b.fail("shape", "holds no particle at this cell size (make cell smaller)");
  out.br.assign(out.x.size(), Vec3::Zero());
  if (b.has("magnetisation") && b.has("sections")) b.fail("sections", "give magnetisation or sections, not both");
  if (b.has("magnetisation")) {
    const Vec3 br = remanence_of(b.map("magnetisation"));
    std::fill(out.br.begin(), out.br.end(), br);
  }
  if (b.has("sections")) {
    const YAML::Node list = b.node("sections");
    if (!list.IsSequence()) b.fail("sections", "must be a list of {axis, from, to, remanence, direction}");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const YamlMap s(list[i], b.file(), b.key_path("sections[" + std::to_string(i) + "]"));
      const Vec3 br = remanence_of(s);
      const int a = axis_of(s);
      const double from = s.quantity("from", unit, range::kCoordinate);
      const double to = s.quantity("to", unit, range::kCoordinate);
      if (to <= from) s.fail("to", "must exceed from");
      for (std::size_t p = 0; p < out.x.size(); ++p) {
        if (out.x[p][a] >= from && out.x[p][a] < to) out.br[p] = br;
      }
    }
  }
  return out;
}

template <int D>
void fill_model(mpm::MpmModel<D>& m, const std::vector<BodyParticles>& bodies, double v0) {
  for (std::size_t bi = 0; bi < bodies.size(); ++bi) {
    m.materials.push_back(bodies[bi].material);
    for (std::size_t p = 0; p < bodies[bi].x.size(); ++p) {
      m.volume.push_back(v0);
      m.mass.push_back(bodies[bi].material.density * v0);
      m.remanence.push_back(bodies[bi].br[p].template head<D>());
      m.material.push_back(static_cast<std::uint16_t>(bi));
      m.section.push_back(static_cast<std::uint16_t>(bi));
    }
  }
}

template <int D>
mpm::MpmModel<D>& model_of(MpmScene& s) {
  if constexpr (D == 2)
    return s.model2;
  else
    return s.model3;
}
template <int D>
const mpm::MpmModel<D>& model_of(const MpmScene& s) {
  if constexpr (D == 2)
    return s.model2;
  else
    return s.model3;
}

}  // namespace

bool is_mpm_scene(const std::filesystem::path& file) {
  const YAML::Node root = parse_yaml(read_text_file(file.string(), "scene file"), file.string());
  return root.IsMap() && static_cast<bool>(root["mpm"]);
}

MpmScene load_mpm_scene(const std::filesystem::path& file) {
  return parse_mpm_scene(read_text_file(file.string(), "scene file"), file.string(), file.parent_path());
}

MpmScene parse_mpm_scene(const std::string& text, const std::string& label, const std::filesystem::path& base_dir) {
  const YamlMap top(parse_yaml(text, label), label, "");
  top.allow_only({"units", "seed", "mpm", "bodies", "clamps", "field", "magnets", "obstacles", "probes"});
  const FileUnits units = file_units(top);
  const Unit& unit = units.len;
  MpmScene sc;
  sc.file = label;
  const YamlMap m = top.map("mpm");
  m.allow_only({"dimension", "plane", "cell", "particles_per_cell", "jitter", "courant", "time_step", "duration",
                "damping", "gravity", "domain", "settle", "snapshots", "video", "step", "newton_tolerance", "frame"});
  sc.implicit = m.has("step") && m.choice<bool>("step", {"explicit", false}, {"implicit", true});
  sc.total_lagrangian = m.has("frame") && m.choice<bool>("frame", {"updated", false}, {"total", true});
  if (sc.total_lagrangian && top.has("obstacles")) {
    m.fail("frame", "total takes no obstacles yet (leave out obstacles, or use frame: updated)");
  }
  if (m.has("newton_tolerance")) {
    if (!sc.implicit) m.fail("newton_tolerance", "is for step: implicit only");
    sc.newton.tolerance = m.quantity("newton_tolerance", Unit{1.0, "cells"}, Range{1e-12, 0.1});
  }
  const long dim = m.has("dimension") ? m.whole("dimension", 2, 3) : 3;
  sc.dimension = static_cast<int>(dim);
  if (m.has("plane") && dim != 2) m.fail("plane", "is for dimension: 2 only (a 3D body has its real depth)");
  const mpm::Plane plane =
      m.has("plane") ? m.choice<mpm::Plane>("plane", {"strain", mpm::Plane::kStrain}, {"stress", mpm::Plane::kStress})
                     : mpm::Plane::kStrain;
  const double cell = m.quantity("cell", unit, range::kSectionSize);
  const double ppc =
      m.has("particles_per_cell") ? static_cast<double>(m.whole("particles_per_cell", 1, 8)) : kDefaultParticlesPerCell;
  mpm::LatticeOptions lattice;
  lattice.spacing = cell / ppc;
  lattice.jitter = m.has("jitter") && m.flag("jitter");
  lattice.seed = seed_of(top, lattice.seed);
  sc.duration = m.quantity("duration", kSeconds, range::kDuration);
  const double damping = m.has("damping") ? m.quantity("damping", Unit{1.0, "1/s"}, Range{0.0, 1e6}) : 0.0;
  const Vec3 gravity = m.has("gravity") ? m.vec3_quantity("gravity", kMetresPerS2, range::kGravity) : Vec3::Zero();
  const YamlMap domain = m.map("domain");
  domain.allow_only({"min", "max", "walls", "friction"});
  const Vec3 dmin = domain.vec3_quantity("min", unit, range::kCoordinate);
  const Vec3 dmax = domain.vec3_quantity("max", unit, range::kCoordinate);
  double cells = 1.0;
  for (int a = 0; a < sc.dimension; ++a) {
    if (dmax[a] <= dmin[a]) domain.fail("max", "must exceed min on every axis of the simulation");
    cells *= (dmax[a] - dmin[a]) / cell;
  }
  if (cells > kMaxNodes) m.fail("cell", "gives more than 2e8 grid cells over the domain (is the unit right?)");
  if (sc.total_lagrangian && domain.has("walls")) {
    domain.fail("walls", "is for frame: updated (in frame: total the domain only bounds the body: a particle leaving "
                         "it ends the run)");
  }
  const mpm::Boundary walls = domain.has("walls") ? boundary_of(domain, "walls") : mpm::Boundary::kSticky;
  const double wall_mu = friction_of(domain, walls);
  if (m.has("settle")) {
    const YamlMap s = m.map("settle");
    s.allow_only({"window", "tolerance"});
    sc.settle_window = s.quantity("window", kSeconds, range::kDuration);
    sc.settle_tolerance = s.quantity("tolerance", unit, range::kDistance);
  }
  if (m.has("snapshots")) sc.snapshot_interval = m.quantity("snapshots", kSeconds, range::kDuration);
  if (m.has("video")) {
    const YamlMap v = m.map("video");
    v.allow_only({"view", "up", "size", "fps", "speed"});
    MpmVideo video;
    if (v.has("view")) video.view = v.direction("view");
    if (v.has("up")) video.up = v.direction("up");
    if (video.view.cross(video.up).norm() < 1e-6) v.fail("up", "must not be parallel to " + v.key_path("view"));
    if (v.has("size")) {
      const std::array<int, 2> size = v.pixel_size("size");
      video.width = size[0];
      video.height = size[1];
    }
    if (v.has("fps")) video.fps = v.quantity("fps", kFramesPerSecond, range::kFrameRate);
    if (v.has("speed")) video.speed = v.quantity("speed", kPlain, range::kPlaybackSpeed);
    sc.video = video;
  }

  // Bodies → particles.
  const YAML::Node blist = top.node("bodies");
  if (!blist.IsSequence() || blist.size() == 0) top.fail("bodies", "must be a non-empty list of bodies");
  std::vector<BodyParticles> bodies;
  std::size_t total = 0;
  for (std::size_t i = 0; i < blist.size(); ++i) {
    const YamlMap b(blist[i], label, "bodies[" + std::to_string(i) + "]");
    bodies.push_back(body_of(b, units, lattice, sc.dimension, base_dir));
    sc.body_names.push_back(bodies.back().name);
    total += bodies.back().x.size();
    if (static_cast<double>(total) > kMaxParticles) b.fail("shape", "gives more than 2e7 particles (make cell larger)");
    for (const Vec3& p : bodies.back().x) {
      for (int a = 0; a < sc.dimension; ++a) {
        if (p[a] <= dmin[a] + cell || p[a] >= dmax[a] - cell) {
          b.fail("shape", "reaches within one cell of the domain's walls (enlarge mpm.domain)");
        }
      }
    }
  }
  if (bodies.size() > 65535) top.fail("bodies", "at most 65535 bodies");
  for (const BodyParticles& b : bodies) sc.positions.insert(sc.positions.end(), b.x.begin(), b.x.end());
  const double v0 = std::pow(lattice.spacing, sc.dimension);

  const double courant = m.has("courant") ? m.quantity("courant", kPlain, Range{0.0, 1.0, true}) : kDefaultCourant;
  auto common = [&](auto& model) {
    using V = std::decay_t<decltype(model.gravity)>;
    constexpr int D = V::RowsAtCompileTime;
    model.cell = cell;
    model.domain_min = dmin.head<D>();
    model.domain_max = dmax.head<D>();
    model.walls = walls;
    model.wall_friction = wall_mu;
    model.plane = plane;
    model.gravity = gravity.head<D>();
    model.damping = damping;
    fill_model<D>(model, bodies, v0);
    if (top.has("clamps")) {
      const YAML::Node list = top.node("clamps");
      if (!list.IsSequence()) top.fail("clamps", "must be a list of {min, max[, velocity]} boxes");
      for (std::size_t i = 0; i < list.size(); ++i) {
        const YamlMap c(list[i], label, "clamps[" + std::to_string(i) + "]");
        c.allow_only({"min", "max", "velocity"});
        const Vec3 lo = c.vec3_quantity("min", unit, range::kCoordinate);
        const Vec3 hi = c.vec3_quantity("max", unit, range::kCoordinate);
        if ((hi.head<D>().array() < lo.head<D>().array()).any()) c.fail("max", "must not be below min");
        const Vec3 velocity = c.has("velocity") ? c.vec3_quantity("velocity", Unit{unit.si, unit.name + "/s"},
                                                                  Range{-range::kSpeed.max, range::kSpeed.max})
                                                : Vec3::Zero();
        model.clamps.push_back({lo.head<D>(), hi.head<D>(), velocity.head<D>()});
      }
    }
    if (top.has("obstacles")) {
      const YAML::Node list = top.node("obstacles");
      if (!list.IsSequence()) top.fail("obstacles", "must be a list of obstacles");
      for (std::size_t i = 0; i < list.size(); ++i) {
        model.obstacles.push_back(obstacle_of(YamlMap(list[i], label, "obstacles[" + std::to_string(i) + "]"), unit,
                                              sc.dimension, cell, base_dir));
      }
    }
    sc.stable_step = model.stable_step(courant);
  };
  if (sc.dimension == 2)
    common(sc.model2);
  else
    common(sc.model3);
  sc.time_step = sc.implicit ? kDefaultImplicitRatio * sc.stable_step : sc.stable_step;
  if (m.has("time_step")) {
    const double dt = m.quantity("time_step", kSeconds, range::kDuration);
    if (!sc.implicit && dt > sc.stable_step) {
      m.fail("time_step", "is above the stable step " + std::to_string(sc.stable_step) +
                              " s (courant · cell / P-wave speed); leave it out to use that step, or take step: "
                              "implicit");
    }
    sc.time_step = dt;
  }

  if (top.has("field")) sc.field = field_of(top.map("field"));
  if (top.has("magnets")) sc.magnets = parse_magnet_list(top, unit);
  if (sc.duration / sc.time_step > 1e9) m.fail("duration", "would take more than a billion steps");

  if (top.has("probes")) {
    const YAML::Node list = top.node("probes");
    if (!list.IsSequence()) top.fail("probes", "must be a list of {name, at}");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const YamlMap p(list[i], label, "probes[" + std::to_string(i) + "]");
      p.allow_only({"name", "at", "radius"});
      MpmProbe probe;
      probe.name = p.text("name");
      probe.at = p.vec3_quantity("at", unit, range::kCoordinate);
      if (sc.dimension == 2) probe.at.z() = 0.0;
      const double r = p.has("radius") ? p.quantity("radius", unit, range::kDistance) : cell;
      for (std::size_t k = 0; k < sc.positions.size(); ++k) {
        if ((sc.positions[k] - probe.at).norm() <= r) probe.particles.push_back(static_cast<std::uint32_t>(k));
      }
      if (probe.particles.empty()) {
        std::string names;
        for (std::size_t b = 0; b < sc.body_names.size(); ++b)
          names += (b > 0 ? ", " : "") + std::string("bodies[") + std::to_string(b) + "]";
        p.fail("at", "has no particle of " + names + " within its radius (one cell by default)");
      }
      sc.probes.push_back(std::move(probe));
    }
  }
  if (sc.settle_window > 0.0 && sc.probes.empty()) m.fail("settle", "needs at least one probe to watch");
  const auto moving = [](const auto& clamps) {
    return std::any_of(clamps.begin(), clamps.end(), [](const auto& c) { return !c.velocity.isZero(); });
  };
  if (sc.settle_window > 0.0 && (moving(sc.model2.clamps) || moving(sc.model3.clamps))) {
    m.fail("settle", "cannot stop a run whose clamp moves (a slow stage would read as rest): leave it out");
  }
  return sc;
}

namespace {

/// Particle positions as 3-vectors (z = 0 in 2D) [m].
template <int D>
std::vector<Vec3> positions3(const mpm::MpmState<D>& state) {
  std::vector<Vec3> out(state.x.size(), Vec3::Zero());
  for (std::size_t i = 0; i < state.x.size(); ++i) out[i].head<D>() = state.x[i];
  return out;
}

template <int D>
MpmResult run_dim(const MpmScene& sc, const std::function<void(double)>& progress) {
  const mpm::MpmModel<D>& model = model_of<D>(sc);
  std::vector<mpm::VecD<D>> x0;
  x0.reserve(sc.positions.size());
  for (const Vec3& p : sc.positions) x0.push_back(p.head<D>());
  mpm::MpmState<D> state = mpm::rest_state<D>(x0);
  mpm::MpmWorkspace<D> ws;
  mpm::TlWorkspace<D> tl_ws;
  const mpm::TlGrid<D> grid = sc.total_lagrangian ? mpm::make_tl_grid<D>(model, state) : mpm::TlGrid<D>{};

  mpm::AppliedField applied;
  magnetics::FieldFunction magnets;
  if (sc.magnets) magnets = magnetics::field_function(*sc.magnets, sc.magnets->rest_poses);
  Vec3 uniform_now = sc.field.at(0.0);  // the uniform part at the current step (read by applied.sample)
  if (magnets) {
    applied.kind = mpm::AppliedField::Kind::kGeneral;
    applied.sample = [&magnets, &uniform_now](const Vec3& x) {
      magnetics::FieldSample s = magnets(x);
      s.b += uniform_now;
      return s;
    };
  } else if (sc.field.any()) {
    applied.kind = mpm::AppliedField::Kind::kUniform;
  }
  auto field_at = [&](double t) -> const mpm::AppliedField& {
    const Vec3 u = sc.field.at(t);
    if (applied.kind == mpm::AppliedField::Kind::kGeneral && u != uniform_now) {
      uniform_now = u;
      ++applied.version;  // the node field cache holds the old uniform part: evaluate again
    }
    applied.uniform = u;
    return applied;
  };
  MpmResult r;
  auto sample = [&] {
    MpmSample s;
    s.time = state.time;
    for (const MpmProbe& p : sc.probes) {
      Vec3 c = Vec3::Zero();
      for (std::uint32_t i : p.particles) c.head<D>() += state.x[i];
      s.probes.push_back(c / static_cast<double>(p.particles.size()));
    }
    s.kinetic_energy = mpm::kinetic_energy(model, state);
    r.samples.push_back(std::move(s));
  };
  auto snapshot = [&] { r.snapshots.push_back({state.time, positions3<D>(state)}); };
  const double sample_every =
      sc.settle_window > 0.0 ? sc.settle_window / 10.0 : std::max(sc.duration / 1000.0, sc.time_step);
  auto frame = [&] { r.frames.push_back(positions3<D>(state)); };
  const double frame_every = sc.video ? sc.video->speed / sc.video->fps : 0.0;
  mpm::RestWatch watch(sc.settle_tolerance);
  sample();
  watch.add(r.samples.back().probes);
  snapshot();
  if (sc.video) frame();
  double next_sample = sample_every, next_snapshot = sc.snapshot_interval, next_progress = 0.0;
  double next_frame = frame_every;
  const Stopwatch clock;
  // Explicit steps: a counted loop (summed step lengths would leave a round-off sliver for one more step). Implicit
  // steps: a failed one is taken again at half the length (ImplicitStepper).
  const long planned = static_cast<long>(std::ceil(sc.duration / sc.time_step - 1e-9));
  mpm::ImplicitStepper<D> implicit(sc.total_lagrangian ? &grid : nullptr, sc.time_step);
  while (sc.implicit ? state.time < sc.duration - 1e-9 * sc.time_step : r.steps < planned) {
    const double remaining = sc.duration - state.time;
    if (!(remaining > 0.0)) break;
    mpm::StepStatus st;
    if (sc.implicit) {
      mpm::ImplicitStats counted;
      st = implicit.step(model, field_at(state.time), state, ws, tl_ws, remaining, sc.newton, &counted);
      r.newton += counted.newton;
      r.cg += counted.cg;
      r.retries = implicit.retries();
    } else {
      const double dt = std::min(sc.time_step, remaining);
      st = sc.total_lagrangian ? mpm::tl_step<D>(model, grid, field_at(state.time), state, tl_ws, dt)
                               : mpm::step(model, field_at(state.time), state, ws, dt);
    }
    ++r.steps;
    if (!st.ok) {
      r.ok = false;
      r.failure = st.cause;  // an implicit step's says the halvings were spent (ImplicitStepper)
      break;
    }
    if (state.time >= next_sample - 1e-12) {
      next_sample += sample_every;
      sample();
      if (sc.settle_window > 0.0 && watch.add(r.samples.back().probes)) {  // every probe at rest
        r.settled = true;
        break;
      }
    }
    if (sc.video && state.time >= next_frame - 1e-12) {
      next_frame += frame_every;
      frame();
    }
    if (sc.snapshot_interval > 0.0 && state.time >= next_snapshot - 1e-12) {
      next_snapshot += sc.snapshot_interval;
      snapshot();
    }
    if (progress && state.time >= next_progress) {
      progress(state.time / sc.duration);
      next_progress += sc.duration / 100.0;
    }
  }
  r.runtime_s = clock.seconds();
  r.time = state.time;
  if (r.samples.back().time < state.time) sample();
  if (r.snapshots.back().first < state.time) snapshot();
  return r;
}

std::string ply_of(const std::vector<Vec3>& pts, const std::vector<std::uint16_t>& body) {
  std::ostringstream o;
  o << "ply\nformat ascii 1.0\ncomment magvine MPM particles, positions in mm\nelement vertex " << pts.size()
    << "\nproperty float x\nproperty float y\nproperty float z\nproperty ushort body\nend_header\n";
  char line[96];
  for (std::size_t i = 0; i < pts.size(); ++i) {
    std::snprintf(line, sizeof line, "%.5g %.5g %.5g %u\n", pts[i].x() / kMmToM, pts[i].y() / kMmToM,
                  pts[i].z() / kMmToM, static_cast<unsigned>(body[i]));
    o << line;
  }
  return o.str();
}

}  // namespace

MpmResult run_mpm_scene(const MpmScene& sc, const std::function<void(double)>& progress) {
  return sc.dimension == 2 ? run_dim<2>(sc, progress) : run_dim<3>(sc, progress);
}

void write_mpm_outputs(const MpmScene& sc, const MpmResult& r, const std::filesystem::path& dir) {
  create_output_directory(dir);
  const std::size_t n = sc.positions.size();
  const std::vector<std::uint16_t>& body = sc.dimension == 2 ? sc.model2.section : sc.model3.section;
  const double cell = sc.dimension == 2 ? sc.model2.cell : sc.model3.cell;
  nlohmann::json j;
  j["scene"] = sc.file;
  j["dimension"] = sc.dimension;
  j["particles"] = n;
  j["cell_mm"] = cell / kMmToM;
  j["time_step_s"] = sc.time_step;
  j["stable_step_s"] = sc.stable_step;
  j["steps"] = r.steps;
  j["step"] = sc.implicit ? "implicit" : "explicit";
  j["frame"] = sc.total_lagrangian ? "total" : "updated";
  if (sc.implicit) {
    j["newton_iterations"] = r.newton;
    j["cg_iterations"] = r.cg;
    j["retried_steps"] = r.retries;
  }
  j["simulated_time_s"] = r.time;
  j["runtime_s"] = r.runtime_s;
  j["particle_steps_per_s"] =
      r.runtime_s > 0.0 ? static_cast<double>(n) * static_cast<double>(r.steps) / r.runtime_s : 0.0;
  j["ok"] = r.ok;
  j["failed"] = !r.ok;
  j["failure"] = r.failure;
  j["settled"] = r.settled;
  j["bodies"] = sc.body_names;
  nlohmann::json probes = nlohmann::json::object();
  for (std::size_t q = 0; q < sc.probes.size() && !r.samples.empty(); ++q) {
    const Vec3 a = r.samples.front().probes[q] / kMmToM, b = r.samples.back().probes[q] / kMmToM;
    probes[sc.probes[q].name] = {{"start_mm", {a.x(), a.y(), a.z()}},
                                 {"end_mm", {b.x(), b.y(), b.z()}},
                                 {"displacement_mm", {b.x() - a.x(), b.y() - a.y(), b.z() - a.z()}},
                                 {"particles", sc.probes[q].particles.size()}};
  }
  j["probes"] = probes;
  j["kinetic_energy_final_J"] = r.samples.empty() ? 0.0 : r.samples.back().kinetic_energy;
  if (!r.ok) {  // a failed run leaves its metrics.json only (docs/cli.md: failed runs)
    j["snapshots"] = nlohmann::json::array();
    if (sc.video) j["video"] = nullptr;  // not rendered
    detail::write_failed_run(dir, j);
    return;
  }
  create_output_directory(dir / "snapshots");
  std::ostringstream csv;
  csv << "t_s";
  for (const MpmProbe& p : sc.probes) csv << ',' << p.name << "_x_mm," << p.name << "_y_mm," << p.name << "_z_mm";
  csv << ",kinetic_energy_J\n";
  csv.precision(9);
  for (const MpmSample& s : r.samples) {
    csv << s.time;
    for (const Vec3& p : s.probes) csv << ',' << p.x() / kMmToM << ',' << p.y() / kMmToM << ',' << p.z() / kMmToM;
    csv << ',' << s.kinetic_energy << '\n';
  }
  nlohmann::json snaps = nlohmann::json::array();
  for (std::size_t k = 0; k < r.snapshots.size(); ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "%04zu.ply", k);
    write_file_atomically(dir / "snapshots" / name, ply_of(r.snapshots[k].second, body));
    snaps.push_back({{"t_s", r.snapshots[k].first}, {"file", std::string("snapshots/") + name}});
  }
  j["snapshots"] = snaps;
  if (sc.video) {
    if (video_plugin_built()) {
      ParticleVideoRequest request;
      request.view = sc.video->view;
      request.up = sc.video->up;
      request.width = sc.video->width;
      request.height = sc.video->height;
      request.fps = sc.video->fps;
      request.radius = cell / 4.0;
      request.frames = &r.frames;
      request.body = &body;
      j["video"] = video_plugin("mpm.video").particle_video(request, dir / "particles").filename().string();
    } else {
      j["video_skipped"] = "built without the render module";
    }
  }
  write_file_atomically(dir / "probes.csv", csv.str());
  write_file_atomically(dir / "metrics.json", j.dump(2) + "\n");
}

}  // namespace magvine::scene
