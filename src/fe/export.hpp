// A symbol of libsubslip_fe's interface: C linkage and visible (the library is built with hidden
// visibility and a version script, exports.map, so nothing else leaves it).
#pragma once

#define SUBSLIP_FE_EXPORT extern "C" __attribute__((visibility("default")))
