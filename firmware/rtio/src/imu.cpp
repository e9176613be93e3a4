#include "zerog/rtio/imu.hpp"

namespace zerog::rtio {

const char* imu_start_status_name(ImuStartStatus status) {
  switch (status) {
    case ImuStartStatus::ok:
      return "ok";
    case ImuStartStatus::open_failed:
      return "open_failed";
    case ImuStartStatus::bad_config:
      return "bad_config";
  }
  return "?";
}

const char* imu_read_status_name(ImuReadStatus status) {
  switch (status) {
    case ImuReadStatus::sample:
      return "sample";
    case ImuReadStatus::timeout:
      return "timeout";
    case ImuReadStatus::disconnected:
      return "disconnected";
    case ImuReadStatus::io_error:
      return "io_error";
    case ImuReadStatus::not_started:
      return "not_started";
    case ImuReadStatus::drained:
      return "drained";
  }
  return "?";
}

}  // namespace zerog::rtio
