#include "zerog/proto/rsi.hpp"

#include <charconv>
#include <cmath>
#include <system_error>

namespace zerog::proto::rsi {

namespace {

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool is_name_start(char c) { return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || c == '_'; }
bool is_name_char(char c) { return is_name_start(c) || is_digit(c) || c == '-' || c == '.'; }

// Strict decimal: [+-]? (digits [. digits*]? | . digits) ([eE] [+-]? digits)?, then from_chars
// (locale-independent, bounded by the view, no allocation). Rejects inf/nan/hex/whitespace.
bool parse_double(std::string_view v, double& out) {
  if (v.empty() || v.size() > kMaxNumberLength) return false;
  std::size_t i = 0;
  if (v[i] == '+' || v[i] == '-') ++i;
  const std::size_t mantissa = i;
  std::size_t digits = 0;
  while (i < v.size() && is_digit(v[i])) ++i, ++digits;
  if (i < v.size() && v[i] == '.') {
    ++i;
    while (i < v.size() && is_digit(v[i])) ++i, ++digits;
  }
  if (digits == 0) return false;
  if (i < v.size() && (v[i] == 'e' || v[i] == 'E')) {
    ++i;
    if (i < v.size() && (v[i] == '+' || v[i] == '-')) ++i;
    std::size_t exp_digits = 0;
    while (i < v.size() && is_digit(v[i])) ++i, ++exp_digits;
    if (exp_digits == 0) return false;
  }
  if (i != v.size()) return false;
  // from_chars takes no leading '+'; a leading '-' it handles itself.
  const char* first = v.data() + (v[0] == '+' ? mantissa : 0);
  const char* last = v.data() + v.size();
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(first, last, value, std::chars_format::general);
  if (ec != std::errc{} || ptr != last || !std::isfinite(value)) return false;
  out = value;
  return true;
}

bool parse_uint(std::string_view v, std::uint64_t& out) {
  if (v.empty() || v.size() > 20) return false;
  std::uint64_t value = 0;
  const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), value, 10);
  if (ec != std::errc{} || ptr != v.data() + v.size()) return false;
  out = value;
  return true;
}

// The attributes one of our elements must carry, each exactly once.
template <std::size_t N>
struct AttributeSet {
  std::array<std::string_view, N> names;
  std::array<double*, N> targets;
};

class Parser {
 public:
  explicit Parser(std::string_view s) : s_(s) {}

  ParseResult parse(RobotMessage& out);
  ParseResult parse(Reply& out);

 private:
  bool fail(ParseStatus status, std::size_t at, const char* reason) {
    result_ = {status, at, reason};
    return false;
  }
  bool at_end() const { return pos_ >= s_.size(); }
  char peek(std::size_t k = 0) const { return pos_ + k < s_.size() ? s_[pos_ + k] : '\0'; }
  bool starts_with(std::string_view lit) const { return s_.substr(pos_).starts_with(lit); }
  std::size_t skip_space() {
    const std::size_t start = pos_;
    while (!at_end() && is_space(s_[pos_])) ++pos_;
    return pos_ - start;
  }
  bool truncated() {
    return fail(ParseStatus::truncated, s_.size(), "input ends inside the message");
  }

  bool name(std::string_view& out);
  // Reads attributes up to and including '>' or '/>'. For each attribute calls
  // on_attribute(name, value, name_offset, value_offset) -> bool.
  template <typename OnAttribute>
  bool attributes(bool& self_closing, OnAttribute&& on_attribute);
  bool end_tag(std::string_view expected);
  bool prolog();
  // An empty element whose attributes are `names`, each at most once, read into `targets`. With
  // `present` null every attribute is required; otherwise any non-empty subset is accepted and
  // its bits (1 << index) are written to *present.
  bool numeric_element(std::string_view element, std::span<const std::string_view> names,
                       std::span<double* const> targets, unsigned* present = nullptr);
  bool ipoc(std::uint64_t& value);
  bool delay(std::uint64_t& value);
  bool skip_element(std::string_view element_name, int depth);
  bool reject_markup();
  // The document walk shared by both message kinds: prolog, root `root` (its attributes are
  // ignored), the children, the end. For each child, on_element(name, offset) returns
  // kElementRead (it read the element), kElementSkip (skip it) or kElementFailed (result_ is set).
  // on_end(end_offset) checks what is required. Writes nothing to the caller on failure.
  template <typename OnElement, typename OnEnd>
  ParseResult document(std::string_view root, const char* root_reason, OnElement&& on_element,
                       OnEnd&& on_end);

  std::string_view s_;
  std::size_t pos_ = 0;
  ParseResult result_;
};

bool Parser::name(std::string_view& out) {
  const std::size_t start = pos_;
  if (at_end()) return truncated();
  if (!is_name_start(peek())) return fail(ParseStatus::syntax, pos_, "expected a name");
  while (!at_end() && is_name_char(s_[pos_])) ++pos_;
  if (pos_ - start > kMaxNameLength) return fail(ParseStatus::syntax, start, "name too long");
  if (at_end()) return truncated();  // the name may go on
  if (peek() == ':') return fail(ParseStatus::unsupported, pos_, "namespaces are not supported");
  out = s_.substr(start, pos_ - start);
  return true;
}

template <typename OnAttribute>
bool Parser::attributes(bool& self_closing, OnAttribute&& on_attribute) {
  while (true) {
    const std::size_t spaces = skip_space();
    if (at_end()) return truncated();
    if (peek() == '/') {
      if (peek(1) == '>') {
        pos_ += 2;
        self_closing = true;
        return true;
      }
      if (pos_ + 1 >= s_.size()) return truncated();
      return fail(ParseStatus::syntax, pos_ + 1, "expected '>' after '/'");
    }
    if (peek() == '>') {
      ++pos_;
      self_closing = false;
      return true;
    }
    if (spaces == 0) return fail(ParseStatus::syntax, pos_, "expected whitespace, '>' or '/>'");
    const std::size_t name_offset = pos_;
    std::string_view attribute;
    if (!name(attribute)) return false;
    skip_space();
    if (at_end()) return truncated();
    if (peek() != '=') return fail(ParseStatus::syntax, pos_, "expected '=' after attribute name");
    ++pos_;
    skip_space();
    if (at_end()) return truncated();
    const char quote = peek();
    if (quote != '"' && quote != '\'') {
      return fail(ParseStatus::syntax, pos_, "expected a quoted attribute value");
    }
    ++pos_;
    const std::size_t value_offset = pos_;
    while (!at_end() && s_[pos_] != quote) {
      if (s_[pos_] == '<') return fail(ParseStatus::syntax, pos_, "'<' in an attribute value");
      ++pos_;
    }
    if (at_end()) return truncated();
    const std::string_view value = s_.substr(value_offset, pos_ - value_offset);
    ++pos_;  // closing quote
    if (!on_attribute(attribute, value, name_offset, value_offset)) return false;
  }
}

bool Parser::end_tag(std::string_view expected) {
  // At "</".
  const std::size_t start = pos_;
  pos_ += 2;
  std::string_view closing;
  if (!name(closing)) return false;
  if (closing != expected) {
    return fail(ParseStatus::syntax, start, "end tag does not match the open element");
  }
  skip_space();
  if (at_end()) return truncated();
  if (peek() != '>') return fail(ParseStatus::syntax, pos_, "expected '>' closing the end tag");
  ++pos_;
  return true;
}

// Markup we do not accept inside the message: comments, CDATA, DTD, processing instructions.
bool Parser::reject_markup() {
  if (peek(1) == '!' || peek(1) == '?') {
    return fail(ParseStatus::unsupported, pos_,
                "comments, CDATA, DTD and processing instructions are not accepted");
  }
  return true;
}

bool Parser::prolog() {
  skip_space();
  if (starts_with("<?xml") && pos_ + 5 < s_.size() && is_space(s_[pos_ + 5])) {
    const std::size_t end = s_.find("?>", pos_);
    if (end == std::string_view::npos) return truncated();
    pos_ = end + 2;
    skip_space();
  }
  return true;
}

bool Parser::numeric_element(std::string_view element, std::span<const std::string_view> names,
                             std::span<double* const> targets, unsigned* present) {
  unsigned seen = 0;
  bool self_closing = false;
  const bool ok = attributes(self_closing, [&](std::string_view attribute, std::string_view value,
                                               std::size_t name_offset, std::size_t value_offset) {
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (attribute != names[i]) continue;
      if (seen & (1u << i)) {
        return fail(ParseStatus::duplicate_attribute, name_offset, "attribute given twice");
      }
      seen |= 1u << i;
      if (!parse_double(value, *targets[i])) {
        return fail(ParseStatus::bad_number, value_offset,
                    "attribute value is not a finite decimal number (or is too long)");
      }
      return true;
    }
    return fail(ParseStatus::unknown_attribute, name_offset, "unknown attribute on this element");
  });
  if (!ok) return false;
  if (present == nullptr ? seen != (1u << names.size()) - 1 : seen == 0) {
    return fail(ParseStatus::missing_attribute, pos_ - 1, "element lacks a required attribute");
  }
  if (present != nullptr) *present = seen;
  if (!self_closing) {
    skip_space();
    if (pos_ + 1 >= s_.size()) return truncated();
    if (!starts_with("</")) {
      return fail(ParseStatus::unexpected_content, pos_, "this element must be empty");
    }
    return end_tag(element);
  }
  return true;
}

bool Parser::ipoc(std::uint64_t& value) {
  bool self_closing = false;
  const bool ok = attributes(
      self_closing, [&](std::string_view, std::string_view, std::size_t at, std::size_t) {
        return fail(ParseStatus::unknown_attribute, at, "IPOC takes no attributes");
      });
  if (!ok) return false;
  if (self_closing) return fail(ParseStatus::bad_number, pos_ - 2, "IPOC is empty");
  skip_space();
  const std::size_t start = pos_;
  while (!at_end() && is_digit(s_[pos_])) ++pos_;
  if (at_end()) return truncated();
  if (!parse_uint(s_.substr(start, pos_ - start), value)) {
    return fail(ParseStatus::bad_number, start, "IPOC is not an unsigned 64-bit integer");
  }
  skip_space();
  if (pos_ + 1 >= s_.size()) return truncated();
  if (!starts_with("</")) return fail(ParseStatus::bad_number, pos_, "IPOC is not an integer");
  return end_tag("IPOC");
}

bool Parser::delay(std::uint64_t& value) {
  bool seen = false;
  bool self_closing = false;
  const bool ok = attributes(self_closing, [&](std::string_view attribute, std::string_view text,
                                               std::size_t name_offset, std::size_t value_offset) {
    if (attribute != "D") {
      return fail(ParseStatus::unknown_attribute, name_offset, "Delay has only the attribute D");
    }
    if (seen) return fail(ParseStatus::duplicate_attribute, name_offset, "attribute given twice");
    seen = true;
    if (!parse_uint(text, value)) {
      return fail(ParseStatus::bad_number, value_offset, "Delay D is not an unsigned integer");
    }
    return true;
  });
  if (!ok) return false;
  if (!seen) return fail(ParseStatus::missing_attribute, pos_ - 1, "Delay lacks D");
  if (!self_closing) {
    skip_space();
    if (pos_ + 1 >= s_.size()) return truncated();
    if (!starts_with("</")) {
      return fail(ParseStatus::unexpected_content, pos_, "this element must be empty");
    }
    return end_tag("Delay");
  }
  return true;
}

// Skips an element we do not use (its start tag already read up to the name), with any
// attributes, text and nested elements. `depth` counts the root as 1.
bool Parser::skip_element(std::string_view element_name, int depth) {
  std::array<std::string_view, kMaxDepth> open{};
  int top = 0;
  open[top++] = element_name;
  auto ignore = [](std::string_view, std::string_view, std::size_t, std::size_t) { return true; };
  bool self_closing = false;
  if (!attributes(self_closing, ignore)) return false;
  if (self_closing) return true;
  while (top > 0) {
    while (!at_end() && s_[pos_] != '<') ++pos_;  // text: taken as is, never decoded
    if (at_end()) return truncated();
    if (peek(1) == '/') {
      if (!end_tag(open[top - 1])) return false;
      --top;
      continue;
    }
    if (!reject_markup()) return false;
    if (depth + top >= kMaxDepth) return fail(ParseStatus::too_deep, pos_, "nesting too deep");
    ++pos_;
    std::string_view child;
    if (!name(child)) return false;
    if (!attributes(self_closing, ignore)) return false;
    if (!self_closing) open[top++] = child;
  }
  return true;
}

enum ElementAction { kElementFailed, kElementRead, kElementSkip };

template <typename OnElement, typename OnEnd>
ParseResult Parser::document(std::string_view root_name, const char* root_reason,
                             OnElement&& on_element, OnEnd&& on_end) {
  if (s_.size() > kMaxMessageBytes) {
    fail(ParseStatus::too_long, kMaxMessageBytes, "message longer than kMaxMessageBytes");
    return result_;
  }
  auto run = [&]() -> bool {
    if (!prolog()) return false;
    if (at_end()) return truncated();
    if (peek() != '<') return fail(ParseStatus::syntax, pos_, "expected '<' and the root element");
    if (!reject_markup()) return false;
    ++pos_;
    std::string_view root;
    const std::size_t root_offset = pos_;
    if (!name(root)) return false;
    if (root != root_name) return fail(ParseStatus::wrong_root, root_offset, root_reason);
    bool self_closing = false;
    auto ignore = [](std::string_view, std::string_view, std::size_t, std::size_t) { return true; };
    if (!attributes(self_closing, ignore)) return false;

    std::size_t end_offset = self_closing ? pos_ - 2 : pos_;  // "/>" of <Rob/>, or "</Rob>"
    while (!self_closing) {
      skip_space();
      if (at_end()) return truncated();
      if (peek() != '<') {
        return fail(ParseStatus::unexpected_content, pos_,
                    "text inside the root element is not accepted");
      }
      if (peek(1) == '/') {
        end_offset = pos_;
        if (!end_tag(root_name)) return false;
        break;
      }
      if (!reject_markup()) return false;
      const std::size_t element_offset = pos_;
      ++pos_;
      std::string_view element;
      if (!name(element)) return false;
      const ElementAction action = on_element(element, element_offset);
      if (action == kElementFailed) return false;
      if (action == kElementSkip && !skip_element(element, 1)) return false;
    }
    skip_space();
    if (!at_end()) {
      return fail(ParseStatus::unexpected_content, pos_, "content after the end of the root");
    }
    return on_end(end_offset);
  };
  if (run()) result_ = ParseResult{};
  return result_;
}

constexpr std::array<std::string_view, 6> kPoseNames{"X", "Y", "Z", "A", "B", "C"};
constexpr std::array<std::string_view, 6> kAxisNames{"A1", "A2", "A3", "A4", "A5", "A6"};
constexpr std::array<std::string_view, kMaxExternalAxes> kExternalAxisNames{"E1", "E2", "E3",
                                                                            "E4", "E5", "E6"};

std::array<double*, 6> pose_targets(double& x, double& y, double& z, double& a, double& b,
                                    double& c) {
  return {&x, &y, &z, &a, &b, &c};
}
template <std::size_t N>
std::array<double*, N> axis_targets(std::array<double, N>& axes) {
  std::array<double*, N> targets{};
  for (std::size_t i = 0; i < N; ++i) targets[i] = &axes[i];
  return targets;
}

ParseResult Parser::parse(RobotMessage& out) {
  RobotMessage msg;
  enum : unsigned { kRIst = 1, kAIPos = 2, kDelay = 4, kIpoc = 8, kEIPos = 16 };
  unsigned seen = 0;
  auto once = [&](unsigned bit, std::size_t at) {
    if (seen & bit) return fail(ParseStatus::duplicate_element, at, "element given twice");
    seen |= bit;
    return true;
  };
  const std::array<double*, 6> pose =
      pose_targets(msg.actual_pose.x_mm, msg.actual_pose.y_mm, msg.actual_pose.z_mm,
                   msg.actual_pose.a_deg, msg.actual_pose.b_deg, msg.actual_pose.c_deg);
  const std::array<double*, 6> axes = axis_targets(msg.joints_deg);
  const std::array<double*, kMaxExternalAxes> external = axis_targets(msg.external_axes);
  unsigned external_present = 0;
  auto on_element = [&](std::string_view element, std::size_t at) {
    bool ok = true;
    if (element == "RIst") {
      ok = once(kRIst, at) && numeric_element(element, kPoseNames, pose);
    } else if (element == "AIPos") {
      ok = once(kAIPos, at) && numeric_element(element, kAxisNames, axes);
    } else if (element == "EIPos") {
      ok = once(kEIPos, at) &&
           numeric_element(element, kExternalAxisNames, external, &external_present);
    } else if (element == "Delay") {
      ok = once(kDelay, at) && delay(msg.delay);
    } else if (element == "IPOC") {
      ok = once(kIpoc, at) && ipoc(msg.ipoc);
    } else {
      if (msg.skipped_elements < 0xFFFFu) ++msg.skipped_elements;
      return kElementSkip;
    }
    return ok ? kElementRead : kElementFailed;
  };
  auto on_end = [&](std::size_t end_offset) {
    if (!(seen & kAIPos)) return fail(ParseStatus::missing_element, end_offset, "AIPos missing");
    if (!(seen & kIpoc)) return fail(ParseStatus::missing_element, end_offset, "IPOC missing");
    msg.has_actual_pose = (seen & kRIst) != 0;
    msg.has_delay = (seen & kDelay) != 0;
    msg.external_axes_present = static_cast<std::uint8_t>(external_present);
    return true;
  };
  const ParseResult r = document("Rob", "root element is not Rob", on_element, on_end);
  if (r.ok()) out = msg;
  return r;
}

ParseResult Parser::parse(Reply& out) {
  Reply reply;
  enum : unsigned { kRKorr = 1, kAKorr = 2, kIpoc = 4 };
  unsigned seen = 0;
  auto once = [&](unsigned bit, std::size_t at) {
    if (seen & bit) return fail(ParseStatus::duplicate_element, at, "element given twice");
    seen |= bit;
    return true;
  };
  const std::array<double*, 6> rkorr =
      pose_targets(reply.rkorr.x_mm, reply.rkorr.y_mm, reply.rkorr.z_mm, reply.rkorr.a_deg,
                   reply.rkorr.b_deg, reply.rkorr.c_deg);
  const std::array<double*, 6> akorr = axis_targets(reply.akorr_deg);
  auto on_element = [&](std::string_view element, std::size_t at) {
    bool ok = true;
    if (element == "RKorr") {
      ok = once(kRKorr, at) && numeric_element(element, kPoseNames, rkorr);
    } else if (element == "AKorr") {
      ok = once(kAKorr, at) && numeric_element(element, kAxisNames, akorr);
    } else if (element == "IPOC") {
      ok = once(kIpoc, at) && ipoc(reply.ipoc);
    } else {
      return kElementSkip;
    }
    return ok ? kElementRead : kElementFailed;
  };
  auto on_end = [&](std::size_t end_offset) {
    if (!(seen & kIpoc)) return fail(ParseStatus::missing_element, end_offset, "IPOC missing");
    reply.has_rkorr = (seen & kRKorr) != 0;
    reply.has_akorr = (seen & kAKorr) != 0;
    return true;
  };
  const ParseResult r = document("Sen", "root element is not Sen", on_element, on_end);
  if (r.ok()) out = reply;
  return r;
}

// Bounded writer into the caller's buffer.
class Writer {
 public:
  explicit Writer(std::span<char> out) : out_(out) {}
  bool text(std::string_view s) {
    if (s.size() > out_.size() - size_) return overflow();
    for (char c : s) out_[size_++] = c;
    return true;
  }
  bool fixed(double value) {
    if (value == 0.0) value = 0.0;  // no "-0.0000"
    char* first = out_.data() + size_;
    const auto [ptr, ec] = std::to_chars(first, out_.data() + out_.size(), value,
                                         std::chars_format::fixed, kReplyDecimals);
    if (ec != std::errc{}) return overflow();
    size_ += static_cast<std::size_t>(ptr - first);
    return true;
  }
  bool integer(std::uint64_t value) {
    char* first = out_.data() + size_;
    const auto [ptr, ec] = std::to_chars(first, out_.data() + out_.size(), value);
    if (ec != std::errc{}) return overflow();
    size_ += static_cast<std::size_t>(ptr - first);
    return true;
  }
  std::size_t size() const { return size_; }

 private:
  static bool overflow() { return false; }
  std::span<char> out_;
  std::size_t size_ = 0;
};

}  // namespace

const char* to_string(ParseStatus status) {
  switch (status) {
    case ParseStatus::ok:
      return "ok";
    case ParseStatus::too_long:
      return "too_long";
    case ParseStatus::truncated:
      return "truncated";
    case ParseStatus::syntax:
      return "syntax";
    case ParseStatus::unsupported:
      return "unsupported";
    case ParseStatus::wrong_root:
      return "wrong_root";
    case ParseStatus::unexpected_content:
      return "unexpected_content";
    case ParseStatus::too_deep:
      return "too_deep";
    case ParseStatus::duplicate_element:
      return "duplicate_element";
    case ParseStatus::missing_element:
      return "missing_element";
    case ParseStatus::missing_attribute:
      return "missing_attribute";
    case ParseStatus::unknown_attribute:
      return "unknown_attribute";
    case ParseStatus::duplicate_attribute:
      return "duplicate_attribute";
    case ParseStatus::bad_number:
      return "bad_number";
  }
  return "?";
}

ParseResult parse_robot_message(std::string_view message, RobotMessage& out) {
  return Parser(message).parse(out);
}

namespace {

bool valid_type(std::string_view type) {
  if (type.empty() || type.size() > kMaxNameLength) return false;
  for (char c : type) {
    if (!is_name_char(c)) return false;
  }
  return true;
}

bool all_finite(std::span<const double> values) {
  for (double v : values) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

// <element N0="v0" N1="v1" .../> with kReplyDecimals digits.
bool numeric_element(Writer& w, std::string_view element, std::span<const std::string_view> names,
                     std::span<const double> values) {
  bool ok = w.text("<") && w.text(element);
  for (std::size_t i = 0; ok && i < names.size(); ++i) {
    ok = w.text(" ") && w.text(names[i]) && w.text("=\"") && w.fixed(values[i]) && w.text("\"");
  }
  return ok && w.text("/>");
}

bool ipoc_element(Writer& w, std::uint64_t ipoc) {
  return w.text("<IPOC>") && w.integer(ipoc) && w.text("</IPOC>");
}

FormatResult sensor_reply(std::string_view element, std::span<const std::string_view> names,
                          std::span<const double> values, std::uint64_t ipoc, std::span<char> out,
                          std::string_view sensor_type) {
  if (!valid_type(sensor_type)) return {FormatStatus::bad_sensor_type, 0};
  if (!all_finite(values)) return {FormatStatus::not_finite, 0};
  Writer w(out);
  const bool ok = w.text("<Sen Type=\"") && w.text(sensor_type) && w.text("\">") &&
                  numeric_element(w, element, names, values) && ipoc_element(w, ipoc) &&
                  w.text("</Sen>");
  if (!ok) return {FormatStatus::buffer_too_small, 0};
  return {FormatStatus::ok, w.size()};
}

}  // namespace

FormatResult format_reply(const Correction& correction, std::uint64_t ipoc, std::span<char> out,
                          std::string_view sensor_type) {
  const std::array<double, 6> values{correction.x_mm,  correction.y_mm,  correction.z_mm,
                                     correction.a_deg, correction.b_deg, correction.c_deg};
  return sensor_reply("RKorr", kPoseNames, values, ipoc, out, sensor_type);
}

FormatResult format_axis_reply(const std::array<double, 6>& akorr_deg, std::uint64_t ipoc,
                               std::span<char> out, std::string_view sensor_type) {
  return sensor_reply("AKorr", kAxisNames, akorr_deg, ipoc, out, sensor_type);
}

FormatResult format_robot_message(const RobotMessage& m, std::span<char> out) {
  const CartesianPose& p = m.actual_pose;
  const std::array<double, 6> pose{p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg};
  if ((m.has_actual_pose && !all_finite(pose)) || !all_finite(m.joints_deg))
    return {FormatStatus::not_finite, 0};
  std::array<std::string_view, kMaxExternalAxes> external_names{};
  std::array<double, kMaxExternalAxes> external_values{};
  std::size_t external_count = 0;
  for (std::size_t i = 0; i < kMaxExternalAxes; ++i) {
    if ((m.external_axes_present & (1u << i)) == 0) continue;
    external_names[external_count] = kExternalAxisNames[i];
    external_values[external_count++] = m.external_axes[i];
  }
  if (!all_finite(std::span<const double>(external_values.data(), external_count)))
    return {FormatStatus::not_finite, 0};
  Writer w(out);
  bool ok = w.text("<Rob Type=\"KUKA\">");
  if (ok && m.has_actual_pose) ok = numeric_element(w, "RIst", kPoseNames, pose);
  ok = ok && numeric_element(w, "AIPos", kAxisNames, m.joints_deg);
  if (ok && external_count > 0) {
    ok = numeric_element(w, "EIPos", std::span(external_names.data(), external_count),
                         std::span<const double>(external_values.data(), external_count));
  }
  if (ok && m.has_delay) ok = w.text("<Delay D=\"") && w.integer(m.delay) && w.text("\"/>");
  ok = ok && ipoc_element(w, m.ipoc) && w.text("</Rob>");
  if (!ok) return {FormatStatus::buffer_too_small, 0};
  return {FormatStatus::ok, w.size()};
}

ParseResult parse_reply(std::string_view message, Reply& out) { return Parser(message).parse(out); }

PoseSi to_si(const CartesianPose& pose) {
  return {{pose.x_mm * 1e-3, pose.y_mm * 1e-3, pose.z_mm * 1e-3},
          {pose.a_deg * kRadPerDeg, pose.b_deg * kRadPerDeg, pose.c_deg * kRadPerDeg}};
}

std::array<double, 6> joints_to_rad(const std::array<double, 6>& joints_deg) {
  std::array<double, 6> rad{};
  for (std::size_t i = 0; i < rad.size(); ++i) rad[i] = joints_deg[i] * kRadPerDeg;
  return rad;
}

double external_axis_to_si(double value, ExternalAxisKind kind) {
  return kind == ExternalAxisKind::linear ? value * 1e-3 : value * kRadPerDeg;
}

Correction correction_from_si(const std::array<double, 3>& translation_m,
                              const std::array<double, 3>& abc_rad) {
  return {translation_m[0] * 1e3,  translation_m[1] * 1e3,  translation_m[2] * 1e3,
          abc_rad[0] / kRadPerDeg, abc_rad[1] / kRadPerDeg, abc_rad[2] / kRadPerDeg};
}

}  // namespace zerog::proto::rsi
