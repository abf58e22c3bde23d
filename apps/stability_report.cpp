#include "stability_report.h"

#include "command.h"

#include "core/atomic_file.h"
#include "validate/stability_part.h"

#include <fmt/core.h>

namespace microsim::app {

int report_stability(const StabilityTable& table, bool failures_only, const std::string& json) {
  StabilityTable shown = table;
  if (failures_only) std::erase_if(shown.rows, [](const auto& r) { return stability_violations(r).empty(); });
  fmt::print("{}", stability_table_markdown(shown));
  const std::size_t violations = table.violation_count();
  fmt::print("\n{} rows, {} evaluations; {} rows exceed their bound: {}\n", table.rows.size(), table.total_evaluations(),
             violations, violations == 0 ? "PASS" : "FAIL");
  if (!json.empty()) write_file_atomically(json, stability_table_json(table).dump(2) + "\n");
  return violations == 0 ? kExitOk : kExitRejected;
}

int report_merged_stability(const StabilityTable& merged, std::size_t parts, const std::string& json) {
  fmt::print(stderr, "merge: {} stability parts, {} evaluations, blocks {}\n", parts, merged.total_evaluations(),
             merged.blocks.to_string());
  return report_stability(merged, /*failures_only=*/false, json);
}

}  // namespace microsim::app
