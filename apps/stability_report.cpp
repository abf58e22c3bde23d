#include "stability_report.h"

#include "command.h"
#include "merge_parts.h"

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

int merge_stability(const std::vector<nlohmann::json>& parts, const std::vector<std::string>& paths,
                    const std::string& json) {
  const std::vector<StabilityTable> read = read_json_parts(parts, paths, read_stability_part);
  const StabilityTable merged = merged_or_usage_error([&] { return merge_stability_parts(read); });
  fmt::print(stderr, "merge: {} stability parts, {} evaluations, blocks {}\n", parts.size(), merged.total_evaluations(),
             merged.blocks.to_string());
  return report_stability(merged, /*failures_only=*/false, json);
}

}  // namespace microsim::app
