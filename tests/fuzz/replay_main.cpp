// A main() for the libFuzzer harnesses without libFuzzer: feeds every file of the directories (or
// files) on the command line to LLVMFuzzerTestOneInput once, in name order. The GCC test build links
// each harness with it (tests/CMakeLists.txt, ctest label `fuzz`), so the committed seed corpora are
// replayed in the release stage and under ASan+UBSan in the asan stage without a clang build. The
// coverage-guided campaigns still need clang and libFuzzer (scripts/fuzz.sh, docs/reliability.md).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <system_error>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);
// Defined by the harnesses that prepare files once (fuzz_recording_toml.cpp); weak so the others link.
extern "C" __attribute__((weak)) int LLVMFuzzerInitialize(int* argc, char*** argv);

namespace {

bool read_file(const std::filesystem::path& p, std::vector<std::uint8_t>* out) {
  std::ifstream in(p, std::ios::binary);
  if (!in) return false;
  out->assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return !in.bad();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s CORPUS_DIR_OR_FILE...\n", argv[0]);
    return 2;
  }
  if (LLVMFuzzerInitialize != nullptr) LLVMFuzzerInitialize(&argc, &argv);
  std::vector<std::filesystem::path> inputs;
  for (int i = 1; i < argc; ++i) {
    const std::filesystem::path arg(argv[i]);
    std::error_code ec;
    if (std::filesystem::is_directory(arg, ec)) {
      for (const auto& e : std::filesystem::directory_iterator(arg, ec))
        if (e.is_regular_file()) inputs.push_back(e.path());
      if (ec) {
        std::fprintf(stderr, "%s: cannot list: %s\n", arg.c_str(), ec.message().c_str());
        return 2;
      }
    } else if (std::filesystem::is_regular_file(arg, ec)) {
      inputs.push_back(arg);
    } else {
      std::fprintf(stderr, "%s: no such file or directory\n", arg.c_str());
      return 2;
    }
  }
  std::sort(inputs.begin(), inputs.end());
  // An empty corpus would pass without exercising anything: refuse it.
  if (inputs.empty()) {
    std::fprintf(stderr, "no inputs found in the arguments\n");
    return 2;
  }
  std::vector<std::uint8_t> bytes;
  for (const auto& p : inputs) {
    if (!read_file(p, &bytes)) {
      std::fprintf(stderr, "%s: cannot read\n", p.c_str());
      return 2;
    }
    LLVMFuzzerTestOneInput(bytes.data(), bytes.size());
  }
  std::printf("replayed %zu inputs\n", inputs.size());
  return 0;
}
