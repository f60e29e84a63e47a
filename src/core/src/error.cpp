#include "magvine/core/error.hpp"

#include <sstream>

namespace magvine {

std::string InputError::format(const std::string& file, int line, const std::string& where, const std::string& what) {
  std::ostringstream s;
  s << file;
  if (line > 0) s << ':' << line;
  if (!where.empty()) s << ": " << where;
  s << ": " << what;
  return s.str();
}

}  // namespace magvine
