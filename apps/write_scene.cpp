#include <cerrno>
#include <cstring>
#include <fstream>
#include <iostream>

#include "apps/commands.hpp"

namespace rubble::apps {

int write_scene_text(const std::string& command, const std::string& output, const std::string& text) {
  if (output == "-") {
    std::cout << text;
    return exit_ok;
  }
  std::ofstream out(output, std::ios::binary);
  out << text;
  out.close();
  if (!out) {
    const int error = errno;
    std::cerr << "rubble " << command << ": output failure: cannot write " << output << ": " << std::strerror(error)
              << "\n";
    return exit_output_failure;
  }
  std::cerr << "rubble " << command << ": wrote " << output << "; run it with: rubble run " << output << "\n";
  return exit_ok;
}

}  // namespace rubble::apps
