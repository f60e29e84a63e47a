#pragma once
/// Contact, ray and inside/outside queries against a static triangle mesh (the airway wall), backed by a 4-wide BVH
/// that Embree's builder makes (binned SAH, one thread; flattened into our own arrays, see triangle_bvh.hpp) and the
/// edge bends of edge_bends.hpp (the quantities of Bullet's btTriangleInfoMap). Embree stays inside the .cpp.
///
/// Contact model (one-sided wall). The mesh is oriented with outward normals (into tissue for an airway lumen).
/// Bodies live on one side of it, the *free side*: by default inside the lumen, against the normals. Every query
/// body is a sphere (centre c, radius r) or a capsule (segment a–b, radius r) and gets contacts
///   point  — on the wall [m],
///   normal — unit, from the wall toward the body: the direction that pushes the body back to the free side,
///   depth  — r − normal·(x − point) > 0, the penetration of the body along `normal` [m], where x is the body's
///            axis point that produced the contact,
/// built per triangle t (with free-side unit normal n_t) from three feature kinds:
///  * Face: the axis point x whose foot lies inside t (centre for a sphere; for a capsule the point of the segment
///    part over t that lies lowest along n_t). normal = n_t, point = foot of x, depth = r − n_t·(x − point). This
///    holds on both sides of t's plane, so a body whose axis has crossed the wall is still pushed back to the free
///    side (depth > r then). Behind the wall by h, the prism over t widens by h·tan(bend) across each valley edge
///    (bend capped at 60°), so an axis point that crossed next to a valley edge or vertex, in the gap between the
///    faces' prisms, is still pushed back. A body lying wholly behind the wall (|n_t·(x − point)| ≥ r) has no
///    contact: use `contains` to detect a body that has left the lumen.
///  * Ridge edge: an edge where the wall bends away from the free side (it juts into the free space; a carina seen
///    from the lumen). The closest point q on the edge to the axis, when the direction q → x lies in the edge's
///    normal cone (the arc from n_t to the neighbour's normal, angle from edge_bends()):
///    normal = that direction, depth = r − |x − q|. Outside the cone a face is the nearest feature and reports it.
///  * Boundary edge (an open mesh's rim): like a ridge whose arc runs from n_t to the in-plane direction m leaving t;
///    behind the rim's plane the normal is m (a knife edge).
/// Flat edges, valley edges (the wall bends toward the free side, e.g. everywhere on the inside of a tube) and
/// vertices inside smooth patches never give contacts of their own: the body's nearest point there always lies on a
/// face (its foot is inside some triangle), so those faces report it with their own normal. This is what removes
/// the snagging edge/vertex normals of a finely tessellated smooth wall. Feet exactly on a shared edge or vertex
/// count for every triangle that shares it (inclusive test, relative tolerance 1e-9 of the triangle size).
/// Vertex contacts: at an end of a ridge edge the vertex is the feature when the body lies in its normal cone (no
/// edge at the vertex heads toward it): normal (x − v)/|x − v|, depth r − |x − v|.
/// Front and back: a face contact whose axis point lies behind the face's plane either means the body crossed
/// that wall (keep: push it back) or that it sits in a neighbouring lumen and reaches this wall from behind
/// through tissue thinner than r (drop: it would push the body through the septum). The nearest feature decides,
/// as in the pseudo-normal inside test: when the nearest face or ridge edge has the axis point in front, back
/// contacts are dropped.
/// Merging: contacts whose normals differ by less than `merge_angle` are one contact, the deepest (a contact close
/// to several kept ones absorbs them all, so the result does not depend on the triangle order); when more distinct
/// contacts exist than the caller's span holds, the deepest are kept. Results are sorted deepest first.
///
/// Model: queries are const, allocation-free and safe to call from several threads at once (each query keeps its
/// scratch on the stack, so there is no workspace to pass). The geometry changes only through refit (a breathing
/// airway), between queries.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "magvine/anatomy/triangle_mesh.hpp"
#include "magvine/core/units.hpp"

namespace magvine::anatomy {

/// Which side of the outward-oriented surface the query bodies live on.
enum class FreeSide {
  kInside,   ///< against the normals: inside a closed lumen (airways; the default)
  kOutside,  ///< along the normals: around obstacles seen from outside
};

/// Construction options of a CollisionWorld.
struct CollisionWorldOptions {
  FreeSide free_side = FreeSide::kInside;
  /// Contacts whose normals differ by less than this angle are merged into the deepest one [rad]. A sphere pressed
  /// into a finely tessellated smooth wall straddles several faces a few degrees apart (a 64-gon tube: 5.6°) and
  /// would otherwise get one contact per face, multiplying the wall force; 20° merges those and keeps genuine
  /// corners (a cap meeting the wall, a carina) apart. 0 merges only identical normals. Must be in [0, π/2).
  double merge_angle = 20.0 * kDegToRad;
};

/// One contact between a query body and the wall (see the file comment for the exact semantics).
struct Contact {
  Vec3 point = Vec3::Zero();    ///< contact point on the wall, world frame [m]
  Vec3 normal = Vec3::UnitZ();  ///< unit normal from the wall toward the body (push-out direction), world frame
  double depth = 0.0;           ///< penetration along `normal`, > 0 [m]
  std::uint32_t triangle = 0;   ///< index of the triangle that produced it, into `mesh().triangles`
};

/// First intersection of a ray with the wall.
struct RayHit {
  double distance = 0.0;        ///< from the ray origin along the unit direction [m]
  Vec3 point = Vec3::Zero();    ///< hit point, world frame [m]
  Vec3 normal = Vec3::UnitZ();  ///< unit face normal turned toward the ray origin (normal·direction ≤ 0)
  std::uint32_t triangle = 0;   ///< index into `mesh().triangles`
  bool front_face = false;      ///< the ray arrived on the side the triangle's outward normal points to
};

/// A triangle near a point (CollisionWorld::triangles_within): the closest point on it and the distance to it.
struct NearTriangle {
  Vec3 point = Vec3::Zero();   ///< closest point on the triangle, world frame [m]
  double distance = 0.0;       ///< |query point − point| [m]
  std::uint32_t triangle = 0;  ///< index into `mesh().triangles`
};

/// What construction found in the mesh.
struct CollisionWorldStats {
  std::size_t triangles = 0;             ///< triangles in the mesh
  std::size_t degenerate_triangles = 0;  ///< zero-area triangles (no normal): ignored by every query
  std::size_t ridge_edges = 0;           ///< triangle edges that bend away from the free side (counted per side)
  std::size_t boundary_edges = 0;        ///< triangle edges without a neighbour (open mesh rims)
  double build_seconds = 0.0;            ///< wall time of BVH + edge bends + tables [s]
  double refit_seconds = 0.0;            ///< wall time of the last refit [s]
};

class CollisionWorld;

/// The triangles near one moving query point, kept across CollisionWorld::triangles_within queries (a robot node
/// queried at every energy evaluation of a solve while it moves a little). A query that misses the cache walks the
/// BVH out to its radius plus `margin` and keeps every triangle within that reach of its point; a later query whose
/// sphere lies inside that reach (|point − fill point| + radius ≤ reach) tests those triangles only. Exact: the
/// answer is the same triangles in the same order (nearest first, ties by index) as without a cache, whatever the
/// cache holds, so results do not depend on it. A neighbourhood of more than `capacity` triangles is queried without
/// it. One cache per query point; not shared between threads. Copyable (a workspace's scratch).
class NearCache {
 public:
  /// `margin` [m] ≥ 0: how far the point may move (less the radius' growth) before a refill. Throws InputError for
  /// a negative or non-finite margin.
  explicit NearCache(double margin = 0.0, std::size_t capacity = 256);
  /// Forgets the triangles: the next query refills.
  void clear() { m_world = 0; }
  double margin() const { return m_margin; }
  /// Queries answered from the kept triangles, and refills, since construction (for benchmarks).
  std::size_t hits() const { return m_hits; }
  std::size_t fills() const { return m_fills; }

 private:
  friend class CollisionWorld;
  double m_margin = 0.0;
  std::size_t m_capacity = 0;
  std::uint64_t m_world = 0;     ///< the id of the world that filled it; 0 when empty
  Vec3 m_centre = Vec3::Zero();  ///< fill point [m]
  double m_reach = 0.0;          ///< fill radius [m]
  std::vector<std::uint32_t> m_slots;
  /// The last whole answer and its query: asked again at the same point and radius (a solver's gradient and
  /// Hessian at one state), it is returned as it was.
  Vec3 m_last_point = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  double m_last_radius = 0.0;
  std::vector<NearTriangle> m_last;
  std::size_t m_hits = 0;
  std::size_t m_fills = 0;
};

/// The candidate triangles of one query sphere, kept across queries: a robot node queried again and again over a
/// solver's iterations while it moves a little. Filled by a sphere query with the BVH leaves within radius + margin
/// of the centre and, of their triangles, those that may touch a sphere of that radius centred anywhere within
/// `margin` (the slot screen widened by the margin); a later query whose centre lies within the margin of the fill
/// centre, with a radius no larger, tests only those, the same leaf tests deciding which, in the same order, so its
/// contacts are exactly those of the query without a cache. Otherwise (moved out, larger radius, another world) the
/// query walks the BVH again and refills the cache. One cache per body; not shared between threads. Storage is
/// allocated once, at construction; a neighbourhood with more candidates than `capacity` is queried without it.
class ContactCache {
 public:
  /// `margin` [m] ≥ 0: how far the centre may move before a refill; `capacity`: the most triangles kept (and
  /// BVH leaves). Throws InputError for a negative or non-finite margin.
  explicit ContactCache(double margin, std::size_t capacity = 1024);
  ~ContactCache();
  ContactCache(ContactCache&&) noexcept;
  ContactCache& operator=(ContactCache&&) noexcept;
  ContactCache(const ContactCache&) = delete;
  ContactCache& operator=(const ContactCache&) = delete;

  /// Forgets the candidates: the next query refills.
  void clear();
  double margin() const { return m_margin; }
  /// Whether the last fill succeeded and the cache is in use.
  bool filled() const;

 private:
  friend class CollisionWorld;
  struct Storage;  ///< the kept leaves (boxes in groups of four, as the BVH's nodes) and triangles
  double m_margin;
  std::unique_ptr<Storage> m_storage;
};

/// Static collision geometry of one mesh [m]. Keeps its own copy of the mesh. Movable, not copyable.
class CollisionWorld {
 public:
  /// Builds the quantized BVH and the edge tables. Throws InputError for an empty mesh, non-finite vertices,
  /// out-of-range indices, more than 2^27 triangles or a bad `merge_angle`.
  explicit CollisionWorld(const TriangleMesh& mesh, const CollisionWorldOptions& options = {});
  ~CollisionWorld();
  CollisionWorld(CollisionWorld&&) noexcept;
  CollisionWorld& operator=(CollisionWorld&&) noexcept;
  CollisionWorld(const CollisionWorld&) = delete;
  CollisionWorld& operator=(const CollisionWorld&) = delete;

  /// Contacts of the sphere (centre [m], radius > 0 [m]) with the wall, written to `out` deepest first.
  /// Returns how many were written (≤ out.size()). Allocation-free.
  std::size_t sphere_contacts(const Vec3& centre, double radius, std::span<Contact> out) const;

  /// As sphere_contacts, with the candidates kept in `cache` (see ContactCache): exactly the same contacts; a
  /// query within the cache's margin skips the BVH walk and most triangle tests. Allocation-free.
  std::size_t sphere_contacts(const Vec3& centre, double radius, std::span<Contact> out, ContactCache& cache) const;

  /// Contacts of the capsule around segment a–b [m] with radius > 0 [m]; a == b is a sphere. As sphere_contacts.
  std::size_t capsule_contacts(const Vec3& a, const Vec3& b, double radius, std::span<Contact> out) const;

  /// The triangles within `radius` [m] of `point` (unsigned point–triangle distance, exact: Ericson's closest
  /// point), degenerate ones left out, written to `out` nearest first. Returns how many lie within the radius, which
  /// may exceed out.size(): then `out` holds the nearest out.size() of them. No sides, no merging: the raw
  /// proximity the robot's wall barrier sums over (robot/terms/wall_barrier.hpp). Allocation-free.
  std::size_t triangles_within(const Vec3& point, double radius, std::span<NearTriangle> out) const;

  /// As triangles_within, with the neighbourhood kept in `cache` (NearCache): the same answer; a query inside the
  /// cache's reach tests the kept triangles only, without a BVH walk. With `stop_within` > 0 the query ends at the
  /// first triangle it meets within that distance of the point, and its answer is partial (that triangle, the
  /// nearest of those it holds; the count so far): for a caller that refuses such a point whatever else lies near it
  /// (the wall barrier's overlap). A partial answer is not kept as the cache's last.
  std::size_t triangles_within(const Vec3& point, double radius, std::span<NearTriangle> out, NearCache& cache,
                               double stop_within = -1.0) const;

  /// First hit of the ray origin + s·direction, 0 ≤ s ≤ max_distance [m], `direction` a unit vector; nullopt when
  /// it hits nothing. Both faces count. A ray through a shared edge or vertex hits (inclusive test). Allocation-free.
  std::optional<RayHit> ray_cast(const Vec3& origin, const Vec3& direction, double max_distance) const;

  /// Whether the segment from a to b [m] passes through the wall (ray_cast along it; a zero-length one does not).
  bool segment_crosses(const Vec3& a, const Vec3& b) const;

  /// Whether `point` [m] is inside the volume the mesh encloses (the lumen of a closed airway), by ray parity: rays
  /// along `parity_directions()` in order until three give an unambiguous count, then the majority of those.
  /// A ray is ambiguous when it passes within 1e-9 (relative) of an edge or vertex, grazes a face or starts on
  /// the surface. Meaningful for closed meshes only; points on the surface may go either way. Allocation-free.
  bool contains(const Vec3& point) const;

  /// The fixed, deliberately irregular unit directions `contains` casts, in order.
  static std::span<const Vec3> parity_directions();

  /// Moves the mesh's vertices to `vertices` (as many as the mesh has, same triangles) and brings every query up to
  /// date: the BVH's boxes are refitted bottom-up over its unchanged tree (no rebuild: the tree's quality degrades
  /// as the motion departs from a smooth one); each triangle's records (plane, edge bends across the build's edge
  /// topology, screen) are recomputed by the first query that reads them, by the build's own laws, so a refitted
  /// world answers as one built on the moved mesh and a refit costs the boxes alone (a body touches a small part of
  /// an airway). One limit: the edge topology and the vertex→triangle lists are the build's, so a triangle that
  /// was degenerate (zero area) at the build stays nobody's neighbour, and one that becomes degenerate turns its
  /// neighbours' shared edges into boundaries, where a fresh build might pair them differently. Lazy filling is safe
  /// under concurrent queries (a per-triangle claim). stats() keeps the build's edge and degeneracy counts. Caches
  /// filled before (NearCache, ContactCache) refill at their next query. Not thread-safe against queries running at the
  /// same time. Throws InputError for a wrong count or a non-finite vertex.
  void refit(std::span<const Vec3> vertices);

  /// The geometry's identity: unique to this world and changed by every refit (what the caches key on).
  std::uint64_t geometry_id() const;

  /// The world's own copy of the mesh [m].
  const TriangleMesh& mesh() const;
  const CollisionWorldOptions& options() const;
  const CollisionWorldStats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

}  // namespace magvine::anatomy
