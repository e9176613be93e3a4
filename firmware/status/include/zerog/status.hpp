#pragma once
// zerog::Status — how a start-up call went (configure(), start(), check_*() across firmware/):
// a code the caller can branch on, a sentence a person can read, and the setting or field it
// concerns (docs/STYLE.md habit 15, as Drake's EventStatus and ros2_control's return_type). Success
// is the default-constructed value and holds nothing: returning it allocates nothing. A failure
// allocates its text once. Header only, no dependencies: every firmware library may use it.
//
//   if (zerog::Status st = server.start(); !st.ok()) print(st.text());   // "port: must be …"
//
// Not for the cycle (a failure allocates): the cycle returns its own enums (loop::Fault, …).
#include <cstdint>
#include <memory>
#include <string>
#include <utility>

namespace zerog {

/// What kind of failure a Status is. Branch on it; the text is for people.
enum class StatusCode : std::uint8_t {
  ok = 0,
  invalid_setting,  ///< a setting's value is refused; setting() names it (field path)
  system_error,     ///< the operating system or a library refused (socket, bind, thread, DDS, file)
  already_started,  ///< start() on something already running
  not_ready,        ///< a precondition is missing (nothing configured, no device given)
};

/// The code's name ("invalid_setting", …), for logs and tests.
constexpr const char* status_code_name(StatusCode code) noexcept {
  switch (code) {
    case StatusCode::ok:
      return "ok";
    case StatusCode::invalid_setting:
      return "invalid_setting";
    case StatusCode::system_error:
      return "system_error";
    case StatusCode::already_started:
      return "already_started";
    case StatusCode::not_ready:
      return "not_ready";
  }
  return "?";
}

class [[nodiscard]] Status {
 public:
  /// Success: no allocation.
  Status() noexcept = default;
  /// A failure. `setting`: the field it concerns, as the configuration struct names it
  /// ("bind_address", "allow[1]", "peers"), "" when it concerns none; `message`: why, without
  /// the setting's name ("must be 1..64, is 1000"). `code` must not be StatusCode::ok.
  Status(StatusCode code, std::string setting, std::string message)
      : detail_(std::make_unique<Detail>(
            Detail{code == StatusCode::ok ? StatusCode::system_error : code, std::move(setting),
                   std::move(message)})) {}
  /// A failure that concerns no setting.
  Status(StatusCode code, std::string message) : Status(code, {}, std::move(message)) {}

  /// A refused setting: invalid_setting naming `setting`.
  static Status invalid(std::string setting, std::string message) {
    return {StatusCode::invalid_setting, std::move(setting), std::move(message)};
  }

  Status(const Status& other)
      : detail_(other.detail_ ? std::make_unique<Detail>(*other.detail_) : nullptr) {}
  Status& operator=(const Status& other) {
    if (this != &other)
      detail_ = other.detail_ ? std::make_unique<Detail>(*other.detail_) : nullptr;
    return *this;
  }
  Status(Status&&) noexcept = default;
  Status& operator=(Status&&) noexcept = default;
  ~Status() = default;

  bool ok() const noexcept { return detail_ == nullptr; }
  StatusCode code() const noexcept { return detail_ ? detail_->code : StatusCode::ok; }
  /// The setting or field concerned ("" on success or when none).
  const std::string& setting() const noexcept { return detail_ ? detail_->setting : empty(); }
  /// Why, without the setting's name ("" on success).
  const std::string& message() const noexcept { return detail_ ? detail_->message : empty(); }
  /// For a person: "SETTING: MESSAGE", or MESSAGE when no setting is concerned; "" on success.
  std::string text() const {
    if (!detail_) return {};
    return detail_->setting.empty() ? detail_->message : detail_->setting + ": " + detail_->message;
  }

  /// The same failure placed within `part` (an enclosing structure or component): a setting
  /// "allow[1]" becomes "modbus.allow[1]" with `part` = "modbus"; without a setting the message
  /// gets "part: " in front ("telemetry: dds_create_domain failed …"). Success stays success.
  Status within(const std::string& part) && {
    if (detail_) {
      if (!detail_->setting.empty()) {
        detail_->setting = part + "." + detail_->setting;
      } else {
        detail_->message = part + ": " + detail_->message;
      }
    }
    return std::move(*this);
  }

 private:
  struct Detail {
    StatusCode code;
    std::string setting;
    std::string message;
  };
  static const std::string& empty() noexcept {
    static const std::string none;
    return none;
  }
  std::unique_ptr<Detail> detail_;  // null: ok
};

}  // namespace zerog
