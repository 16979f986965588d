// libFuzzer target: recording.toml (formats/src/recording.cpp). A bad file must throw ptda::Error.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.hpp"
#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/formats/recording.hpp"
#include "ptda/formats/wav.hpp"

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  // The files a valid recording.toml names, so the fuzzer reaches the checks behind them.
  ptda::formats::write_wav(ptda::fuzz::scratch_dir() / "vibration.wav", 25600,
                           ptda::formats::WavSampleFormat::kPcm16, {{0.0F, 0.5F}, {0.25F, -0.5F}});
  (void)ptda::fuzz::write_scratch("can.log", "(1700000000.000000) can0 184#0011223344556677\n");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  (void)ptda::fuzz::write_scratch("recording.toml", ptda::fuzz::as_text(data, size));
  try {
    const auto meta = ptda::formats::read_recording_meta(ptda::fuzz::scratch_dir());
    // Every consumer converts start_time to ns: an accepted file must convert without UB.
    (void)ptda::seconds_to_ns(meta.start_time_s);
  } catch (const ptda::Error&) {
  }
  return 0;
}
