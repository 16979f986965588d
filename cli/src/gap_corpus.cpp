// gap-bench corpus reader (docs/gap.md "Bench").
#include "ptda/cli/gap_corpus.hpp"

#include <fstream>
#include <sstream>
#include <string>

#include "ptda/cli/jsonl.hpp"
#include "ptda/common/error.hpp"

namespace ptda::cli {
namespace {

std::string read_text(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  if (!f) throw Error(p.string() + ": cannot open");
  std::ostringstream s;
  s << f.rdbuf();
  if (f.bad()) throw Error(p.string() + ": read failed");
  return s.str();
}

const JsonValue& field(const JsonValue& o, const char* key, JsonValue::Kind kind, const std::string& where) {
  if (o.kind != JsonValue::Kind::kObject) throw Error(where + ": not a JSON object");
  const auto it = o.object.find(key);
  if (it == o.object.end()) throw Error(where + ": missing \"" + key + "\"");
  if (it->second.kind != kind) throw Error(where + ": \"" + key + "\" has the wrong type");
  return it->second;
}

void check_format(const JsonValue& j, const char* format, const std::string& where) {
  if (field(j, "format", JsonValue::Kind::kString, where).string != format) {
    throw Error(where + ": \"format\" is not \"" + format + "\"");
  }
  if (field(j, "version", JsonValue::Kind::kNumber, where).number != 1.0) {
    throw Error(where + ": unsupported \"version\" (this build reads 1)");
  }
}

void read_truth(const std::filesystem::path& path, gap::CorpusCase& c) {
  const std::string where = path.string();
  const JsonValue j = parse_json(read_text(path), where);
  check_format(j, "ptda-gap-truth", where);
  const std::string& cat = field(j, "category", JsonValue::Kind::kString, where).string;
  if (cat == "effect") {
    c.category = gap::CaseCategory::kEffect;
  } else if (cat == "control") {
    c.category = gap::CaseCategory::kControl;
  } else if (cat == "out_of_library") {
    c.category = gap::CaseCategory::kOutOfLibrary;
  } else {
    throw Error(where + ": \"category\" must be effect, control or out_of_library, not \"" + cat + "\"");
  }
  if (const auto d = j.object.find("description");
      d != j.object.end() && d->second.kind == JsonValue::Kind::kString) {
    c.description = d->second.string;
  }
  const JsonValue& effects = field(j, "effects", JsonValue::Kind::kArray, where);
  for (std::size_t i = 0; i < effects.array.size(); ++i) {
    const std::string w = where + ": effects[" + std::to_string(i) + "]";
    const std::string& kind = field(effects.array[i], "kind", JsonValue::Kind::kString, w).string;
    const auto k = sim::effect_kind_from_name(kind);
    if (!k) throw Error(w + ": unknown effect kind \"" + kind + "\"");
    sim::EffectSpec e = sim::EffectSpec::with_defaults(*k);
    const JsonValue& params = field(effects.array[i], "params", JsonValue::Kind::kObject, w);
    for (const auto& [name, v] : params.object) {
      if (v.kind != JsonValue::Kind::kNumber) throw Error(w + ": parameter \"" + name + "\" is not a number");
      bool known = false;
      for (const sim::EffectParamInfo& p : sim::effect_info(*k).params) known = known || name == p.name;
      if (!known) throw Error(w + ": " + kind + " has no parameter \"" + name + "\"");
      e.set(name, v.number);
    }
    c.truth.push_back(std::move(e));
  }
  if (c.category == gap::CaseCategory::kEffect && c.truth.empty()) {
    throw Error(where + ": category \"effect\" needs at least one entry in \"effects\"");
  }
  if (c.category != gap::CaseCategory::kEffect && !c.truth.empty()) {
    throw Error(where + ": category \"" + cat + "\" must not list library effects");
  }
}

}  // namespace

gap::Corpus load_gap_corpus(const std::filesystem::path& dir) {
  const std::filesystem::path manifest = dir / "corpus.json";
  const std::string where = manifest.string();
  const JsonValue j = parse_json(read_text(manifest), where);
  check_format(j, "ptda-gap-corpus", where);
  gap::Corpus corpus;
  corpus.dir = dir;
  corpus.name = field(j, "name", JsonValue::Kind::kString, where).string;
  const JsonValue& cases = field(j, "cases", JsonValue::Kind::kArray, where);
  if (cases.array.empty()) throw Error(where + ": \"cases\" is empty");
  for (std::size_t i = 0; i < cases.array.size(); ++i) {
    const std::string w = where + ": cases[" + std::to_string(i) + "]";
    const JsonValue& cj = cases.array[i];
    gap::CorpusCase c;
    c.name = field(cj, "name", JsonValue::Kind::kString, w).string;
    c.recording = dir / field(cj, "recording", JsonValue::Kind::kString, w).string;
    c.nominal = dir / field(cj, "nominal", JsonValue::Kind::kString, w).string;
    const std::filesystem::path truth = dir / field(cj, "truth", JsonValue::Kind::kString, w).string;
    if (!std::filesystem::is_directory(c.recording)) {
      throw Error(w + ": recording directory " + c.recording.string() + " does not exist");
    }
    if (!std::filesystem::is_regular_file(c.nominal)) {
      throw Error(w + ": nominal scenario " + c.nominal.string() + " does not exist");
    }
    read_truth(truth, c);
    for (const gap::CorpusCase& other : corpus.cases) {
      if (other.name == c.name) throw Error(w + ": case name \"" + c.name + "\" appears twice");
    }
    corpus.cases.push_back(std::move(c));
  }
  return corpus;
}

}  // namespace ptda::cli
