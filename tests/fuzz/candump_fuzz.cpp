// candump text (firmware/proto candump.hpp: the -L log form and the default columns with every
// timestamp form), as `zerog decode-can` reads a user's recording.
// The parser reports errors as a CandumpError (line, column, reason) and never throws.
//
// Properties: the text and the stream overloads agree (same records, same error); an error names
// a line of the input; every record formats back (format_candump_line) into a line that parses
// to the same record (a CAN FD record without its payload, which the parser does not keep).
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_util.hpp"
#include "zerog/io/candump.hpp"

using zerog::io::CandumpError;
using zerog::io::CandumpLineKind;
using zerog::io::CandumpRecord;

namespace {

bool same_record(const CandumpRecord& a, const CandumpRecord& b) {
  return a.timestamp_ns == b.timestamp_ns && a.interface == b.interface && a.frame == b.frame &&
         a.direction == b.direction && a.fd == b.fd;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = zerog::fuzz::as_text(data, size);
  const zerog::proto::CanFilter pass_all{};

  std::vector<CandumpRecord> records;
  CandumpError error;
  const bool ok = zerog::io::parse_candump(text, pass_all, records, error);

  std::istringstream stream{std::string(text)};
  std::vector<CandumpRecord> records_from_stream;
  CandumpError stream_error;
  const bool stream_ok =
      zerog::io::parse_candump(stream, pass_all, records_from_stream, stream_error);
  ZEROG_FUZZ_CHECK(ok == stream_ok);
  ZEROG_FUZZ_CHECK(records.size() == records_from_stream.size());
  for (std::size_t i = 0; i < records.size(); ++i)
    ZEROG_FUZZ_CHECK(same_record(records[i], records_from_stream[i]));
  if (!ok) {
    ZEROG_FUZZ_CHECK(error.line == stream_error.line && error.column == stream_error.column);
    ZEROG_FUZZ_CHECK(error.reason == stream_error.reason);
    ZEROG_FUZZ_CHECK(error.line >= 1 && error.column >= 1);
    ZEROG_FUZZ_CHECK(!error.message().empty());
  }

  for (const CandumpRecord& record : records) {
    ZEROG_FUZZ_CHECK(record.frame.len <= zerog::proto::kCanMaxDataLength);
    const std::string line = zerog::io::format_candump_line(record);
    CandumpRecord back;
    CandumpError line_error;
    const CandumpLineKind kind = zerog::io::parse_candump_line(line, 1, back, line_error);
    if (kind != CandumpLineKind::record) {
      std::fprintf(stderr, "formatted line does not parse: '%s': %s\n", line.c_str(),
                   line_error.message().c_str());
    }
    ZEROG_FUZZ_CHECK(kind == CandumpLineKind::record);
    ZEROG_FUZZ_CHECK(same_record(record, back));
  }
  return 0;
}
