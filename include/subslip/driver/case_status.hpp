// Where a case of a run stands when a session starts, as its result sink reports it.
#pragma once

namespace subslip::driver {

// A new run has every case pending. A restart (the result file of an earlier session) keeps
// completed and failed cases and continues an interrupted one.
enum class CaseStatus { pending, interrupted, completed, failed };

}  // namespace subslip::driver
