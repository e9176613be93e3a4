#include "zerog/rtio/ft_sensor.hpp"

namespace zerog::rtio {

const char* ft_sample_status_name(FtSampleStatus status) {
  switch (status) {
    case FtSampleStatus::ok:
      return "ok";
    case FtSampleStatus::warning:
      return "warning";
    case FtSampleStatus::critical:
      return "critical";
    case FtSampleStatus::saturated:
      return "saturated";
  }
  return "?";
}

const char* ft_start_status_name(FtStartStatus status) {
  switch (status) {
    case FtStartStatus::ok:
      return "ok";
    case FtStartStatus::bad_config:
      return "bad_config";
    case FtStartStatus::no_response:
      return "no_response";
    case FtStartStatus::readout_failed:
      return "readout_failed";
    case FtStartStatus::unknown_units:
      return "unknown_units";
    case FtStartStatus::io_error:
      return "io_error";
  }
  return "?";
}

const char* ft_read_status_name(FtReadStatus status) {
  switch (status) {
    case FtReadStatus::sample:
      return "sample";
    case FtReadStatus::timeout:
      return "timeout";
    case FtReadStatus::not_started:
      return "not_started";
    case FtReadStatus::tx_failed:
      return "tx_failed";
    case FtReadStatus::io_error:
      return "io_error";
  }
  return "?";
}

}  // namespace zerog::rtio
