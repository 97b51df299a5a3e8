// AlignScans on the wire: the header's options, edges and the result.
#pragma once

#include "absl/status/statusor.h"
#include "mlsreg/multiview/align_scans.h"
#include "mlsreg/v1/mlsreg.pb.h"

namespace mlsreg::wire {

// Every option of the header (pairs, method, parameters, overlaps, anchor, initial poses),
// library defaults for unset fields and auto for METHOD_UNSPECIFIED; errors name the field
// ("header.initial_poses[2]: ..."). The scan count is checked by the library.
absl::StatusOr<AlignOptions> AlignOptionsFromProto(const v1::AlignScansHeader& header);
// Every option set explicitly; the scans are left to the caller.
void AlignOptionsToProto(const AlignOptions& options, v1::AlignScansHeader* header);

void ToProto(const AlignEdge& edge, v1::AlignEdge* out);
// The registration as far as the wire carries it: transform, termination, iterations, time, and
// a one-entry trace holding its last RMSE.
AlignEdge FromProto(const v1::AlignEdge& edge);
void ToProto(const AlignResult& result, v1::AlignScansResult* out);
AlignResult FromProto(const v1::AlignScansResult& result);

}  // namespace mlsreg::wire
