// Every conversion between the mlsreg.v1 wire types and the library's domain types, one header
// per concept. Errors are absl::InvalidArgumentError whose message starts with the offending
// field path (e.g. "source.points[12]: non-finite coordinate").
#pragma once

#include "mlsreg/wire/align_codec.h"       // AlignScans options, edges, results
#include "mlsreg/wire/cloud_codec.h"       // clouds, chunks
#include "mlsreg/wire/enum_codec.h"        // enums through the library's name tables
#include "mlsreg/wire/options_codec.h"     // method and registration parameters
#include "mlsreg/wire/register_request.h"  // the Register header
#include "mlsreg/wire/results_codec.h"     // progress, results, ground-truth errors
#include "mlsreg/wire/status.h"            // absl::Status <-> grpc::Status
#include "mlsreg/wire/targets_codec.h"     // target descriptions
#include "mlsreg/wire/transform_codec.h"   // rigid transforms
