// libFuzzer target for the scene parser (issue 8, item 3): any byte string given to parse_scene
// must either parse or throw SceneError. Anything else (another exception, a crash, a sanitizer
// report, a hang) is a bug that libFuzzer reports with the input that caused it.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "simulation/scene_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const rubble::Scene scene = rubble::parse_scene(text, "fuzz.toml");
    (void)scene;
  } catch (const rubble::SceneError&) {
    // The expected answer to bad input.
  }
  return 0;
}
