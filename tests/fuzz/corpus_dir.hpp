#pragma once
// The command line of the seed-corpus programs (make_*_seeds.cpp): one argument, the corpus folder,
// created with its parents. Returns 0 and sets *dir, or the exit code after saying why.

#include <cstdio>
#include <filesystem>
#include <string>
#include <system_error>

namespace hwr::fuzz {

inline int corpus_dir_from_args(int argc, char** argv, std::string* dir) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <corpus folder>\n", argv[0]);
    return 2;
  }
  *dir = argv[1];
  std::error_code ec;
  std::filesystem::create_directories(*dir, ec);
  if (ec) {
    std::fprintf(stderr, "cannot create %s: %s\n", dir->c_str(), ec.message().c_str());
    return 1;
  }
  return 0;
}

}  // namespace hwr::fuzz
