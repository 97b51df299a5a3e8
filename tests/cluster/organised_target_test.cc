// Reverse calibration through the service: an organised target's pinhole intrinsics travel with
// the upload, and RC-P registrations served by the real server match the in-process ones.
#include <gtest/gtest.h>

#include "mlsreg/client/client.h"
#include "mlsreg/registration/registration.h"
#include "server/server.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

TEST(OrganisedTargetTest, IntrinsicsTravelAndRcPMatchesInProcess) {
  const PinholeIntrinsics camera{80, 60, 50.0, 50.0, 39.5, 29.5};
  auto depth = [](double x, double y) { return 2.0 + 0.4 * testing::BumpyHeight(x, y); };
  const PointCloud scan = testing::RenderDepthImage(camera, depth);
  PointCloud source = testing::SampleBumpySurface(5000, -0.4, 0.4, 9);
  for (Vec3& p : source.points) p.z() = depth(p.x(), p.y());

  server::ServerConfig config;
  config.listen = "127.0.0.1:0";
  config.workers = 1;
  auto server = server::MlsregServer::Start(config);
  ASSERT_TRUE(server.ok()) << server.status();
  client::ClientOptions options;
  options.address = (*server)->address();
  auto client = client::Client::Connect(options);
  ASSERT_TRUE(client.ok());
  ASSERT_TRUE((*client)->UploadTarget("organised", scan).ok());

  RegistrationOptions registration;
  registration.method = Method::kRcP;
  registration.num_samples = 1000;
  const Matrix4 initial = RandomPerturbation(3.0, 0.02, Vec3(0, 0, 2), 4);
  auto remote = (*client)->Register("organised", source, initial, registration);
  ASSERT_TRUE(remote.ok()) << remote.status();
  auto target = Target::Build(scan);
  ASSERT_TRUE(target.ok());
  auto local = Register(**target, source, initial, registration);
  ASSERT_TRUE(local.ok());
  EXPECT_EQ(remote->result.transform, local->transform);
  EXPECT_GE(remote->result.iterations, 2);

  // A target uploaded without intrinsics cannot serve reverse calibration.
  PointCloud unorganised = scan;
  unorganised.intrinsics.reset();
  ASSERT_TRUE((*client)->UploadTarget("unorganised", unorganised).ok());
  auto refused = (*client)->Register("unorganised", source, initial, registration);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(refused.status().message().find("intrinsics"), std::string::npos);
}

}  // namespace
}  // namespace mlsreg
