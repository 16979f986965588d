// Reader of gap-bench corpus directories (docs/gap.md "Bench", "Corpora"): DIR/corpus.json lists the
// cases; each case has a recording directory, a nominal scenario and a truth.json. Thread: any (one
// call at a time per directory). Allocates, reads files; throws ptda::Error naming file and field.
#pragma once

#include <filesystem>

#include "ptda/gap/bench.hpp"

namespace ptda::cli {

/// Reads DIR/corpus.json ({"format": "ptda-gap-corpus", "version": 1, "name", "cases": [{"name",
/// "recording", "nominal", "truth"}]}, paths relative to DIR) and every case's truth file
/// ({"format": "ptda-gap-truth", "version": 1, "category": "effect"|"control"|"out_of_library",
/// "description", "effects": [{"kind", "params": {name: value}}]}). Effect parameters not given keep
/// the catalog default; an unknown kind or parameter, a missing file, an effect case without effects
/// or a control/out-of-library case with library effects is an error.
[[nodiscard]] gap::Corpus load_gap_corpus(const std::filesystem::path& dir);

}  // namespace ptda::cli
