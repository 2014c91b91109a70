// Where forward Euler goes unstable, for subslip_extreme_report: the measured critical step of a
// contact and of a one-system crystal against the linearised estimate 2 / lambda.
#pragma once

namespace subslip::bench {

// Prints the section "Forward Euler stability limit" (Markdown) to standard output.
void report_forward_euler();

}  // namespace subslip::bench
