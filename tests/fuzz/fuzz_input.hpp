// The fuzz targets' input as a file: the loaders under test take paths, as
// the programs do. The file lives in the temporary directory and is removed
// when the input is done.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace markloop::fuzz {

class InputFile {
 public:
  // `suffix` matters where the reader goes by the name (".yaml" for OpenCV).
  InputFile(const std::uint8_t* data, std::size_t size, const char* suffix) {
    path_ =
        (std::filesystem::temp_directory_path() / ("markloop-fuzz-" + std::to_string(::getpid()) + suffix))
            .string();
    std::FILE* f = std::fopen(path_.c_str(), "wb");
    if (f == nullptr || (size > 0 && std::fwrite(data, 1, size, f) != size) || std::fclose(f) != 0) {
      std::perror(path_.c_str());
      std::abort();  // the harness, not the code under test, failed
    }
  }
  ~InputFile() { std::remove(path_.c_str()); }
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace markloop::fuzz
