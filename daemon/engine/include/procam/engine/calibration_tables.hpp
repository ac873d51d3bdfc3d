// SPDX-License-Identifier: MIT
// Calibration tables through the product (docs/calibration.md): a rig config
// names table files in "calibration_tables" ({"<table name>": "<path relative
// to the config file>"}); the daemon and offline tools load and validate them
// and copy them into every session's rig description as
// "calibration_tables": {"<table name>": <table JSON>} (plugin_abi.h /
// PROTOCOL.md 8), which the SDK's sdk::Rig::table() reads.
//
// Table format v1 ("procam-calibration-table"): see docs/calibration.md.
// Errors: invalid_argument naming the config file, the field
// ("calibration_tables.<name>") and what is wrong; not_found for a missing
// file. Thread-safety: reentrant.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"

namespace procam::engine {

// Checks one table document against format v1 with the SDK's reader
// (procam/sdk/calibration_table.hpp parse_table: "format", "version" 1,
// "name", "x"/"y" {name, unit}, >= 2 finite "samples" [x, y] with x strictly
// increasing and y strictly monotonic, optional "extra" and "made", no other
// keys). `what` prefixes messages (e.g. "rig config 'r.json': ...").
Status check_calibration_table(const nlohmann::json& table, const std::string& what);

// The rig config's "calibration_tables" (absent: an empty object), each file
// read (relative to `config_dir`) and checked; the key in the config must
// equal the table's "name". `config_file` names the file in messages.
Result<nlohmann::json> load_calibration_tables(const nlohmann::json& rig_config, const std::string& config_dir,
                                               const std::string& config_file);

// `rig_config` without its "calibration_tables" key (the hardware backends
// do not know it and reject unknown keys).
nlohmann::json without_calibration_tables(nlohmann::json rig_config);

// One line per table for `procam rig`: name, x/y names and units, x and y
// ranges, sample count and the "made" fields.
std::string describe_calibration_table(const std::string& name, const nlohmann::json& table);

}  // namespace procam::engine
