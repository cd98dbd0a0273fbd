// Fuzz target: E57 files (acquisition/e57_io.h): the header, the pages' CRC-32C, the XML section, the
// compressed vectors' packets and bit-pack codec, and the scans as one cloud and as views. The first byte
// selects how the rest is taken: even, as the file itself (mutations mostly meet the page checksums); odd, as
// the file's logical byte stream, paged with valid checksums before reading (so mutations reach the header,
// XML and packet checks).

#include <string>

#include "acquisition/e57_io.h"
#include "acquisition/formats/e57_pages.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  std::string bytes(reinterpret_cast<const char*>(data + 1), size - 1);
  if (data[0] % 2 == 1) bytes = s2m::formats::e57::PageLogicalStream(bytes);
  const s2m::fuzz::ScratchFile file(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size(),
                                    ".e57");
  s2m::fuzz::ExpectOnlyFormatErrors([&] {
    const s2m::E57Data e57 = s2m::ReadE57(file.path());
    (void)s2m::ToScanSet(e57, file.path());
    (void)s2m::ToOneCloud(e57, file.path());
  });
  return 0;
}
