// libFuzzer target: the WAV reader (formats/src/wav.cpp) on an arbitrary file. Reads every channel
// in bounded chunks; a bad file must throw ptda::Error.
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "fuzz_support.hpp"
#include "ptda/common/error.hpp"
#include "ptda/formats/wav.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = ptda::fuzz::write_scratch("in.wav", ptda::fuzz::as_text(data, size));
  try {
    ptda::formats::WavReader r(path);
    std::array<float, 256> buf{};
    for (std::uint16_t ch = 0; ch < r.info().channels && ch < 4; ++ch) {
      r.seek(0);
      // Bounded: a header may claim far more frames than the file holds.
      for (int i = 0; i < 64; ++i)
        if (r.read(ch, std::span<float>(buf)) == 0) break;
    }
    ptda::formats::WavInfo info;
    (void)ptda::formats::read_wav_channel(path, 0, &info);
  } catch (const ptda::Error&) {
  }
  return 0;
}
