#pragma once
// Internal to the formats (namespace zerog::formats::detail): the rig's TOML reader, shared by
// read_rig and the importer's [rig] table (host/io). The strict TOML reader itself is public
// (zerog/formats/toml_table.hpp); the sources name it through detail as well.
#include <filesystem>
#include <string>

#include "zerog/formats/log.hpp"
#include "zerog/formats/toml_table.hpp"

namespace zerog::formats::detail {

using formats::number_text;
using formats::parse_toml_file;
using formats::throw_at;
using formats::TomlTable;

/// A transform table `{ p_m = [x, y, z], q_wxyz = [w, x, y, z] }` (m; unit quaternion within
/// 1e-3, returned normalised): the rig's flange_sensor and sensor_imu, a robot's flange.
Transform transform_of(const TomlTable& t);

/// Reads a rig from a TOML table. `embedded` (the [rig] table of an import mapping): the keys
/// `format` and `version` are optional and `sample_period_s` may be absent — `*has_period` tells.
/// `key_prefix` is prepended to key names in messages (e.g. "rig.").
Rig rig_from_toml(const toml::table& table, const std::filesystem::path& file, bool embedded,
                  const std::string& key_prefix, bool* has_period);

}  // namespace zerog::formats::detail
