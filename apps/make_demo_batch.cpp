// Writes a synthetic batch for `scan2model batch` (acquisition/synthetic_batch.h, docs/batch.md):
//   s2m_make_demo_batch <dir> [pots sherds shells]
// then: scan2model batch <dir>/batch.csv --report

#include <exception>
#include <iostream>
#include <string>

#include "acquisition/synthetic_batch.h"

int main(int argc, char** argv) {
  if (argc != 2 && argc != 5) {
    std::cerr << "usage: s2m_make_demo_batch <dir> [pots sherds shells]\n";
    return 2;
  }
  try {
    s2m::SyntheticBatchOptions options;
    if (argc == 5) {
      options.pots = std::stoi(argv[2]);
      options.sherds = std::stoi(argv[3]);
      options.shells = std::stoi(argv[4]);
    }
    const auto manifest = s2m::WriteSyntheticBatch(argv[1], options);
    std::cout << "wrote " << manifest.string() << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "s2m_make_demo_batch: error: " << e.what() << "\n";
    return 3;
  }
}
