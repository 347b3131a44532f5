// vtsim_fuzz_corpus [-v] DIR [TARGET...]: runs every target (or the named ones) over each file of
// DIR/<target>/, the checked-in seeds and findings (ctest fuzz_corpus). A finding aborts with the
// target's message after naming the file. -v prints each input's refusals (InputError messages). Exit 0 when every input was accepted or refused with an
// InputError; 2 for bad arguments or an empty corpus directory.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "fuzz_targets.h"

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  using vtsim::fuzz::Target;
  const bool verbose = argc > 1 && std::string(argv[1]) == "-v";
  const int first = verbose ? 2 : 1;
  if (argc <= first) {
    std::fprintf(stderr, "usage: %s [-v] CORPUS_DIR [TARGET...]\n", argv[0]);
    return 2;
  }
  std::vector<const Target*> run;
  for (int i = first + 1; i < argc; ++i) {
    const Target* t = vtsim::fuzz::find_target(argv[i]);
    if (t == nullptr) {
      std::fprintf(stderr, "%s: no fuzz target '%s'\n", argv[0], argv[i]);
      return 2;
    }
    run.push_back(t);
  }
  if (run.empty())
    for (const Target& t : vtsim::fuzz::targets()) run.push_back(&t);
  for (const Target* t : run) {
    const fs::path dir = fs::path(argv[first]) / t->name;
    std::vector<fs::path> files;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec))
      if (e.is_regular_file()) files.push_back(e.path());
    if (ec || files.empty()) {
      std::fprintf(stderr, "%s: no inputs in %s\n", argv[0], dir.c_str());
      return 2;
    }
    std::sort(files.begin(), files.end());
    for (const fs::path& f : files) {
      std::ifstream in(f, std::ios::binary);
      const std::vector<char> bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
      std::fprintf(stderr, "%s: %s\n", t->name, f.filename().c_str());
      t->run(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
      const std::vector<std::string> refused = vtsim::fuzz::take_refusals();
      if (verbose) {
        if (refused.empty()) std::printf("%s/%s: accepted\n", t->name, f.filename().c_str());
        for (const std::string& r : refused) std::printf("%s/%s: refused: %s\n", t->name, f.filename().c_str(), r.c_str());
      }
    }
    std::printf("%s: %zu inputs, no findings\n", t->name, files.size());
  }
  return 0;
}
