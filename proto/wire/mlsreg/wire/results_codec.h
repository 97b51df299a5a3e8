// Registration results on the wire: Progress per iteration, the final Result, terminations and
// ground-truth errors.
#pragma once

#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/registration/result.h"
#include "mlsreg/v1/mlsreg.pb.h"

namespace mlsreg::wire {

void ToProto(const IterationReport& report, v1::Progress* out);
void ToProto(const RegistrationResult& result, v1::Result* out);
IterationReport FromProto(const v1::Progress& progress);
// The library result as far as the wire carries it (the trace is left empty).
RegistrationResult FromProto(const v1::Result& result);
v1::Termination TerminationToProto(Termination t);
Termination TerminationFromProto(v1::Termination t);  // unknown values: kMaxIterations
void ToProto(const PoseError& error, v1::GroundTruthError* out);
void ToProto(const VerificationScore& score, v1::VerificationScore* out);
VerificationScore FromProto(const v1::VerificationScore& score);
PoseError FromProto(const v1::GroundTruthError& error);

}  // namespace mlsreg::wire
