// Writes the binary seeds of the fuzz corpora (small WAV files in each sample format and a small
// baseline) into tests/fuzz/corpus/. Run once by hand when the formats change:
//   build/fuzz/tests/fuzz/fuzz_make_seeds tests/fuzz/corpus
// The text seeds (candump lines, TOML files, IIO types) are copies of the golden files.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <vector>

#include "ptda/formats/baseline_file.hpp"
#include "ptda/formats/wav.hpp"

namespace fs = std::filesystem;
using ptda::formats::WavSampleFormat;

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s CORPUS_DIR\n", argv[0]);
    return 2;
  }
  const fs::path root = argv[1];
  fs::create_directories(root / "wav");
  fs::create_directories(root / "baseline");
  std::vector<std::vector<float>> ch(2, std::vector<float>(16));
  for (std::size_t i = 0; i < 16; ++i) {
    ch[0][i] = static_cast<float>(std::sin(0.4 * static_cast<double>(i)) * 0.5);
    ch[1][i] = static_cast<float>(i) / 16.0F - 0.5F;
  }
  const std::pair<WavSampleFormat, const char*> formats[] = {{WavSampleFormat::kPcm16, "pcm16"},
                                                             {WavSampleFormat::kPcm24, "pcm24"},
                                                             {WavSampleFormat::kPcm32, "pcm32"},
                                                             {WavSampleFormat::kFloat32, "float32"}};
  for (const auto& [f, name] : formats)
    ptda::formats::write_wav(root / "wav" / (std::string(name) + ".wav"), 25600, f, ch);

  ptda::dsp::Baseline b;
  b.fs_hz = 25600.0;
  b.window_len = 8;
  b.gearbox = {ptda::dsp::GearboxInfo::Kind::kCycloidal, 10, 40, 41, 164.0};
  b.policy = {ptda::dsp::ThresholdPolicy::Kind::kQuantile, 1e-3, 0.1};
  for (std::uint32_t k = 0; k < 2; ++k) {
    ptda::dsp::ClassBaseline c;
    c.segment = {k, static_cast<std::int8_t>(k == 0 ? 1 : -1), 0.5 + k, 0.05, 1.25, 12 + k};
    c.n_windows = 40 + k;
    c.mean_magnitude.assign(b.window_len / 2 + 1, 0.25F);
    c.tda_mean.assign(b.window_len, -0.5F);
    for (std::size_t m = 0; m < ptda::dsp::kMethodCount; ++m) {
      c.thresholds[m] = {{0.5, 2.0}, {3.0, 4.0}};
      c.rms_stats[m] = {1.0, 0.1, 0.8, 1.2, 40};
      c.entropy_stats[m] = {3.5, 0.2, 3.0, 4.0, 40};
    }
    b.classes.push_back(c);
  }
  b.source = "fuzz seed";
  const auto bytes = ptda::formats::serialize_baseline(b);
  std::ofstream(root / "baseline" / "two_classes.ptdab", std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  return 0;
}
