#pragma once
// The plausible range of every number a scene, magnets or MPM file gives, SI. Every range that more than one key
// shares lives here (a range that belongs to one key alone, e.g. a volume fraction or a field of view, sits beside
// that key in its parser); every parser checks its numbers with YamlMap::quantity, and docs/scenes.md (validation
// of inputs) lists them. They are wide
// (a value outside is a typo or a unit slip, not an unusual experiment) and finite, so that nothing derived from
// them (stiffnesses, masses, fields, step counts) overflows. Private to the scene module.

#include "yaml_reader.hpp"

namespace magvine::scene::range {

// Geometry [m].
inline constexpr Range kCoordinate{-10.0, 10.0};         ///< any position: base, magnets, targets, moves
inline constexpr Range kBodyLength{0.0, 10.0, true};     ///< a robot's length, an inserted length
inline constexpr Range kSectionSize{0.0, 1.0, true};     ///< diameters, widths, thicknesses of a body
inline constexpr Range kLayerThickness{0.0, 0.1, true};  ///< a vine's wall or skin
inline constexpr Range kSpacing{0.0, 10.0, true};        ///< node and edge spacings
inline constexpr Range kMagnetSize{0.0, 2.0, true};      ///< a magnet's diameter or length
inline constexpr Range kMagnetVolume{0.0, 1.0, true};    ///< [m³]
inline constexpr Range kDistance{0.0, 10.0, true};       ///< navigator distances and leads, tolerances
inline constexpr Range kSmallDistance{0.0, 10.0};        ///< lengths that may be 0 (tether keyframes)

// Materials.
inline constexpr Range kModulus{0.0, 1e12, true};            ///< Young's and shear moduli [Pa]
inline constexpr Range kStrength{0.0, 1e10, true};           ///< a film's tensile strength [Pa]
inline constexpr Range kDensity{0.0, 3e4};                   ///< [kg/m³] (osmium: 22,590)
inline constexpr Range kPressure{0.0, 1e7};                  ///< [Pa] (10 MPa)
inline constexpr Range kPositivePressure{0.0, 1e7, true};    ///< [Pa]
inline constexpr Range kRemanence{-3.0, 3.0};                ///< Br, J [T] (no magnet material exceeds ~1.5 T)
inline constexpr Range kPolarisation{0.0, 3.0, true};        ///< a magnet's J [T]
inline constexpr Range kMoment{-1e6, 1e6};                   ///< a dipole's moment components [A·m²]
inline constexpr Range kField{-10.0, 10.0};                  ///< uniform field components [T]
inline constexpr Range kRemanenceMagnitude{0.0, 3.0, true};  ///< a design's |Br| [T]
inline constexpr Range kRemanenceBound{0.0, 3.0};            ///< a design's bounds on |Br| [T]
inline constexpr Range kUniformFieldBound{0.0, 10.0, true};  ///< a design's bound on |B| [T]
inline constexpr Range kFriction{0.0, 10.0};                 ///< Coulomb μ

// Growth law.
inline constexpr Range kLengthYield{0.0, 1e9};           ///< c_L [Pa/m]
inline constexpr Range kTurningYield{0.0, 1e7};          ///< c_θ [Pa/rad]
inline constexpr Range kExtensibility{0.0, 1.0};         ///< K [m/(s·Pa)]
inline constexpr Range kSpeed{0.0, 10.0};                ///< insertion and retraction speeds [m/s]
inline constexpr Range kPositiveSpeed{0.0, 10.0, true};  ///< the navigator's retraction speed [m/s]

// Time [s] and loads.
inline constexpr Range kTime{0.0, 1e6};                   ///< keyframe and command times
inline constexpr Range kDuration{0.0, 1e6, true};         ///< durations, intervals, step sizes
inline constexpr Range kForce{0.0, 1e3};                  ///< a tool's force [N]
inline constexpr Range kForcePerLength{0.0, 1e6};         ///< friction along a tool [N/m]
inline constexpr Range kGravity{-1e3, 1e3};               ///< gravity components [m/s²]
inline constexpr Range kSolverTolerance{0.0, 1.0, true};  ///< scaled-gradient tolerance

// Videos.
inline constexpr Range kFrameRate{0.0, 240.0, true};    ///< frames per second of a video
inline constexpr Range kPlaybackSpeed{0.0, 1e3, true};  ///< simulated seconds per video second

}  // namespace magvine::scene::range
