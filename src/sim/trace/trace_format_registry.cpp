// The one table of trace formats: adding a format is one file in impl/ and one line here (and its
// declaration). The order is detection's (a format's sniff sees a line only if none before it
// claimed it) and that of every list of names.
#include "sim/trace/trace_format.h"

namespace vtsim {

TraceFormat trace_format_native();  // impl/format_native.cpp
TraceFormat trace_format_tum();     // impl/format_tum.cpp
TraceFormat trace_format_kitti();   // impl/format_kitti.cpp
TraceFormat trace_format_euroc();   // impl/format_euroc.cpp

const Registry<TraceFormat>& trace_formats() {
  static const Registry<TraceFormat> table("trace format", {
      trace_format_native(),
      trace_format_tum(),
      trace_format_kitti(),
      trace_format_euroc(),
  });
  return table;
}

}  // namespace vtsim
