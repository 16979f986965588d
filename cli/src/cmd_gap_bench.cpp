// Placeholder until the command lands (replaced by its implementation).
#include <ostream>

#include "ptda/cli/commands.hpp"
#include "ptda/common/error.hpp"

namespace ptda::cli {
int cmd_gap_bench(std::span<const std::string> /*args*/, std::ostream& /*out*/) {
  throw ptda::Error("ptda: this command is not implemented yet");
}
}  // namespace ptda::cli
