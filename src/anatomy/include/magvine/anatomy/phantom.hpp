#pragma once
/// Generated phantoms: a synthetic bronchial tree and bench phantoms mirroring the thesis's experiments (straight
/// tube, Y bifurcation, S-bend around two obstacles, constricted channel). Each comes as a closed lumen mesh
/// [m, outward normals], its ground-truth airway graph and metadata. Generation is deterministic: the same
/// parameters and seed give a bit-identical mesh.
///
/// Frames. Bronchial tree: the trachea runs along −z from its entry at the origin (the top of the mesh is the
/// plane z = 0), so a robot enters from the top; the first bifurcation plane is x–z, child 0 of the trachea heads
/// to +x. Bench phantoms lie on the table: the entry wall is the plane x = 0, the channel runs along +x, z is up.
/// The graph's first node sits one inscribed radius inside the entry wall, so every node has its inscribed sphere
/// inside the lumen.
///
/// Parameter structs are SI (m, rad); file-facing names in the metadata carry unit suffixes (`_mm`, `_deg`).

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "magvine/anatomy/airway_graph.hpp"
#include "magvine/anatomy/triangle_mesh.hpp"

namespace magvine::anatomy {

/// The generated phantom kinds.
enum class PhantomKind {
  kBronchialTree,  ///< "bronchial_tree": trachea to generation ≥ 6
  kTube,           ///< "tube": straight circular tube
  kYBifurcation,   ///< "y_bifurcation": one symmetric bifurcation
  kSBend,          ///< "s_bend": flat channel with two obstacles forcing an S-shaped path
  kConstriction,   ///< "constriction": tube squeezed to a slot of adjustable gap
};

/// Name and one-line description of a kind, for `magvine phantom --help`.
struct PhantomKindInfo {
  PhantomKind kind;
  std::string_view name;
  std::string_view description;
};

/// All kinds, in a fixed order.
std::span<const PhantomKindInfo> phantom_kinds();
/// The kind called `name` ("bronchial_tree", "tube", "y_bifurcation", "s_bend", "constriction"), or nullopt.
std::optional<PhantomKind> parse_phantom_kind(std::string_view name);
/// The file-facing name of a kind.
std::string_view to_string(PhantomKind kind);

/// Which morphometric table drives the symmetric bronchial tree (shared/reference/airways.md §1).
enum class AirwayTable {
  kWeibelA,    ///< Weibel 1963 model A diameters and lengths (gens 0–10; 18 mm trachea) + Horsfield angles
  kHorsfield,  ///< Horsfield 1994 diameters, lengths and branching angles (gens 0–6; 16.5 mm trachea)
};

/// File-facing names of the tables: "weibel_a", "horsfield".
std::string_view to_string(AirwayTable table);
/// The table called `name`, or nullopt.
std::optional<AirwayTable> parse_airway_table(std::string_view name);

/// Bronchial tree. Symmetric (flow_ratio = 0.5): every branch of generation g has the table's diameter d(g), length
/// L(g) and branching angle θ(g) (each daughter's angle to its parent's axis; Horsfield's values for g = 1–6 also
/// with Weibel A, which has no angles; 35° beyond). Asymmetric (flow_ratio < 0.5): the trachea keeps the table
/// values; below it Kitaoka, Takaki & Suki 1999's rules apply at every split: d1 = d0·r^(1/n) (minor daughter,
/// child 1), d2 = d0·(1−r)^(1/n) (major, child 0), minimum-power angles cos θ1 = (1 + r^(4/n) − (1−r)^(4/n)) /
/// (2 r^(2/n)) and the same with r ↔ 1−r for θ2, length L = 3d. The branching plane turns 90° about the
/// parent axis at every generation. Branches are capsules (round cones with equal radii) joined at each
/// bifurcation (parent + children) by a smooth union with blend radius blend_factor × the branch radius; other
/// branches meet with a sharp union, so near neighbours do not bridge. Leaf ends are hemispherical, the trachea
/// top is cut flat at z = 0, one trachea radius above the trachea's first graph node.
/// Clearance: branches that share no node (all but parent/child and siblings) must keep a wall gap ≥ clearance
/// (segment–segment distance − both radii); for a branch and its grandparent or its parent's sibling, which touch
/// its parent too, only axis points outside the parent's capsule count (inside it the lumen is shared anyway,
/// as with Weibel A's short generation 3, L/d = 1.4). For a sibling pair that violates it the generator tries, in
/// a fixed order (first success wins): the parent as planned or lengthened (×1.15, 1.3, 1.5); for each, the pair's
/// plane turned about the parent axis (±15° steps up to ±90°); for each, every child on its own in 13 poses (its
/// branching angle ×0.7–1.3, capped at 80°, and its length ×1.0–0.6). Otherwise generation fails with InputError
/// naming the two branches. Adjustments are listed in the metadata notes.
struct BronchialTreeParams {
  AirwayTable table = AirwayTable::kWeibelA;
  int max_generation = 6;         ///< deepest generation (trachea = 0): 1…10 for Weibel A, 1…6 for Horsfield
  double flow_ratio = 0.5;        ///< Kitaoka flow-dividing ratio r ∈ [0.2, 0.5]; 0.5 = symmetric table tree
  double diameter_exponent = 2.8; ///< Kitaoka diameter exponent n ∈ [2, 4]
  double length_jitter = 0.0;     ///< relative half-range of uniform length jitter, [0, 0.5)
  double angle_jitter = 0.0;      ///< half-range of uniform branching-angle jitter [rad], [0, 0.35]
  double rotation_jitter = 0.0;   ///< half-range of uniform jitter on the 90° plane rotation [rad], [0, 0.8]
  std::uint64_t seed = 1;         ///< seed of the jitter (recorded even when jitter is off)
  double clearance = 1.0e-3;      ///< minimum wall gap between non-adjacent branches [m], ≥ 2 × spacing
  double blend_factor = 0.5;      ///< junction blend radius / branch radius, [0, 1]
  double spacing = 0.4e-3;        ///< meshing grid spacing [m]; ≤ half the smallest radius and ≤ clearance / 2
};

/// Straight tube (make_tube), axis +x from the entry wall at x = 0 to x = length.
/// Defaults: Ø12 mm, comfortably above the thesis's Ø4–8 mm robots; 120 mm long, above the 80 mm free length of
/// thesis 4.7.1.
struct TubeParams {
  double diameter = 12e-3;  ///< inner diameter [m]
  double length = 120e-3;   ///< [m]
  int segments = 64;        ///< vertices around the circumference, ≥ 8
  bool capped = true;       ///< false leaves both ends open (not watertight)
};

/// Symmetric Y: a parent tube along +x from the entry wall at x = 0, then two daughters at ±branch_angle in the
/// horizontal x–y plane (child 0 towards +y). Junction and ends as in the bronchial tree. Defaults: parent Ø12 mm
/// (main-bronchus size, Weibel A gen 1: 12.2 mm), daughters Ø9.5 mm (Hess–Murray 12·2^(−1/3) = 9.52), branching
/// angle 35° each (Kitaoka's symmetric minimum-power angle 34.9°, Horsfield gen 1–2: 36°/35°); lengths chosen for
/// a bench: 60 mm parent, 50 mm daughters.
struct YBifurcationParams {
  double parent_diameter = 12e-3;    ///< [m]
  double parent_length = 60e-3;      ///< first graph node to the bifurcation [m] (the wall is a radius before)
  double daughter_diameter = 9.5e-3; ///< [m]
  double daughter_length = 50e-3;    ///< bifurcation to blind end centre [m]
  double branch_angle = 0.6108652381980153;  ///< each daughter's angle to the parent axis [rad] (35°)
  double blend_factor = 0.5;         ///< junction blend radius / daughter radius
  double spacing = 0.4e-3;           ///< meshing grid spacing [m]; ≤ daughter_diameter / 4
};

/// S-bend: a flat rectangular channel (the table-top arena of thesis 4.7.3, fig 4.10) with two full-height
/// obstacles reaching in from alternate side walls past the centre line, so the path from the entry at (0, 0, 0)
/// to the far wall must swing to +y around the first and to −y around the second. The thesis gives no
/// dimensions; these are chosen for its Ø8 mm robot: channel 160 × 60 × 20 mm (x × y × z), obstacles 20 mm thick
/// (along x, rounded ends of radius 10 mm) at x = 50 and 110 mm, reaching 36 mm from their wall (6 mm past the
/// centre line), leaving 24 mm gaps. Inner edges rounded with edge_rounding.
struct SBendParams {
  double length = 160e-3;             ///< channel length along x [m]
  double width = 60e-3;               ///< channel width along y [m]
  double height = 20e-3;              ///< channel height along z [m]
  double obstacle_thickness = 20e-3;  ///< obstacle size along x (its end is a half-cylinder of half this) [m]
  double obstacle_reach = 36e-3;      ///< how far each obstacle reaches from its side wall [m], < width
  double first_obstacle_x = 50e-3;    ///< centre of the first obstacle (from the −y wall) [m]
  double second_obstacle_x = 110e-3;  ///< centre of the second obstacle (from the +y wall) [m]
  double edge_rounding = 2e-3;        ///< rounding radius of the channel's edges and corners [m]
  double spacing = 1e-3;              ///< meshing grid spacing [m]; ≤ height / 8. 1 mm: 20 cells across the
                                      ///< height, 0.2 M triangles (0.4 mm would give 1.35 M for flat walls)
};

/// Constricted channel: a Ø12 mm tube along +x (flat ends at x = 0 and x = length) squeezed between two flat jaws
/// (normal ±y) to a slot of width `gap` over `constriction_length`, as in thesis 5.6.2 (a 25 mm long gap whose
/// width a linear actuator set; widths 2.5–7 mm there, 5, 3 and 2 mm in 4.7.2). The jaw edges are rounded with
/// jaw_rounding, so the slot is exactly `gap` wide over constriction_length − 2·jaw_rounding.
struct ConstrictionParams {
  double diameter = 12e-3;             ///< tube inner diameter [m]
  double length = 100e-3;              ///< [m]
  double gap = 3e-3;                   ///< slot width at the constriction [m], 0 < gap < diameter (thesis: 2–5 mm)
  double constriction_length = 25e-3;  ///< jaw length along x [m] (thesis 5.6.2: 25 mm)
  double constriction_x = 50e-3;       ///< jaw centre along x [m]
  double jaw_rounding = 2e-3;          ///< rounding radius of the jaw edges [m]
  double spacing = 0.4e-3;             ///< meshing grid spacing [m]; gap ≥ 4 × spacing
};

/// Parameters of any kind.
using PhantomParams =
    std::variant<BronchialTreeParams, TubeParams, YBifurcationParams, SBendParams, ConstrictionParams>;

/// The default parameters of a kind.
PhantomParams default_params(PhantomKind kind);

/// One number of a kind's parameters under its file-facing name (`gap_mm`, `branch_angle_deg`, `max_generation`),
/// bound to its field: the command line's options (`--gap-mm`) and the Python API's keywords (`gap_mm=3`) are made
/// from these. A value in the name's unit becomes SI as value × scale.
struct PhantomOption {
  std::string name;
  std::string help;
  std::variant<double*, int*, std::uint64_t*> field;
  double scale = 1.0;  ///< SI per file unit: kMmToM for `_mm`, kDegToRad for `_deg`, else 1
};
/// The numeric parameters of `params` (its kind's), in the command line's order. The bronchial tree's `table` and the
/// tube's `open` are not numbers: parse_airway_table and TubeParams::capped.
std::vector<PhantomOption> phantom_options(PhantomParams& params);

/// One parameter as recorded in the metadata file (file-facing name with unit suffix).
struct PhantomParameter {
  std::string name;                                                  ///< e.g. "gap_mm", "max_generation"
  std::variant<double, std::int64_t, bool, std::string> value;
};

/// What was generated.
struct PhantomMetadata {
  PhantomKind kind = PhantomKind::kTube;
  std::uint64_t seed = 0;                   ///< jitter seed (0 for kinds without randomness)
  std::vector<PhantomParameter> parameters; ///< every parameter used, mm / deg
  std::vector<std::string> notes;           ///< sources, model choices, clearance adjustments
};

/// A generated phantom.
struct Phantom {
  TriangleMesh mesh;      ///< lumen wall [m], outward normals (into tissue), watertight unless asked open
  AirwayGraph graph;      ///< ground-truth centreline [m]
  PhantomMetadata meta;
};

/// Generators. Each validates its parameters and throws InputError("phantom <kind>", "<name>_mm", ...) naming the
/// parameter, its value and the allowed range.
Phantom make_bronchial_tree(const BronchialTreeParams& params);
Phantom make_tube_phantom(const TubeParams& params);
Phantom make_y_bifurcation(const YBifurcationParams& params);
Phantom make_s_bend(const SBendParams& params);
Phantom make_constriction(const ConstrictionParams& params);
/// Dispatches on the parameter type.
Phantom make_phantom(const PhantomParams& params);

/// The branch table used by the symmetric tree: diameter [m], length [m] and branching angle [rad] of generation g
/// (angle 0 for g = 0). Throws std::out_of_range beyond the table.
struct GenerationGeometry {
  double diameter = 0.0;
  double length = 0.0;
  double branch_angle = 0.0;
};
GenerationGeometry airway_table(AirwayTable table, int generation);
/// Deepest generation a table covers (10 for Weibel A here, 6 for Horsfield).
int airway_table_depth(AirwayTable table);

/// Metadata as JSON text: {"units": "mm", "kind", "seed", "parameters": {...}, "notes": [...],
/// "triangles", "vertices", "branches"}.
std::string phantom_metadata_json(const Phantom& phantom);

/// Writes `stl_path` (binary STL in mm, via write_stl), `<stem>.graph.json` (airway graph, mm) and
/// `<stem>.meta.json` beside it. Each file is written atomically; the JSON files are committed only after the STL
/// succeeded. InputError on I/O failure.
void write_phantom(const Phantom& phantom, const std::filesystem::path& stl_path);

/// The graph and metadata paths write_phantom() uses for `stl_path`.
std::filesystem::path phantom_graph_path(const std::filesystem::path& stl_path);
std::filesystem::path phantom_meta_path(const std::filesystem::path& stl_path);

}  // namespace magvine::anatomy
