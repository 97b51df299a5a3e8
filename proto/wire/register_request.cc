#include "mlsreg/wire/register_request.h"

#include "mlsreg/wire/cloud_codec.h"
#include "mlsreg/wire/options_codec.h"
#include "mlsreg/wire/transform_codec.h"

namespace mlsreg::wire {

void BuildRegisterHeader(const std::string& target_id, const PointCloud& source,
                         v1::ScalarType scalar_type, const RegistrationOptions& options,
                         const Matrix4& initial, const std::optional<Matrix4>& ground_truth,
                         v1::RegisterHeader* header, std::string* payload) {
  header->set_target_id(target_id);
  v1::Method method;
  OptionsToProto(options, &method, header->mutable_parameters());
  header->set_method(method);
  ToProto(initial, header->mutable_initial_transform());
  if (ground_truth) ToProto(*ground_truth, header->mutable_ground_truth());
  EncodeCloud(source, scalar_type, header->mutable_source(), payload);
}

}  // namespace mlsreg::wire
