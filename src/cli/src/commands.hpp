#pragma once
// The verbs of the magvine executable. Each returns the process exit code and throws InputError for bad input.

#include <optional>
#include <string>

#include "magvine/core/eigen_types.hpp"

namespace magvine::cli {

struct FieldArgs {
  std::string magnets;
  std::string points;
  std::string out;  // empty: stdout
};
int run_field(const FieldArgs& args);

struct FieldMapArgs {
  std::string magnets;
  std::string plane = "xz";
  std::string units = "mm";
  std::string center = "0,0,0";
  double extent = 300.0;  // half-width, in `units`
  int resolution = 201;
  std::string out_dir;
};
int run_field_map(const FieldMapArgs& args);

struct StudyArgs {
  std::string magnets;  // the first cylinder in it is studied
  std::string out_dir;
};
int run_study_field_models(const StudyArgs& args);

}  // namespace magvine::cli
