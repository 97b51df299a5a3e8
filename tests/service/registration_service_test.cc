// RegistrationService over a real channel: results identical to the library's, progress
// streaming, validation of every malformed request while good work goes on, cancellation,
// deadlines and admission control.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "mlsreg/registration/finish.h"
#include "mlsreg/registration/registration.h"
#include "mlsreg/wire/convert.h"
#include "service_test_support.h"

namespace mlsreg::service_test {
namespace {

Matrix4 FromWire(const v1::Transform& t) {
  auto m = wire::FromProto(t, "transform");
  EXPECT_TRUE(m.ok()) << m.status();
  return m.ok() ? *m : Matrix4(Matrix4::Identity());
}

class RegistrationServiceTest : public ::testing::Test {
 protected:
  void StartWith(ServerConfig config) {
    server_ = StartServer(config);
    ASSERT_NE(server_, nullptr);
    client_ = Connect(server_->port());
    ASSERT_TRUE(Upload(client_, "bun045", Bun045()).ok());
  }
  int active_jobs() { return Stats(client_).active_jobs(); }

  std::unique_ptr<MlsregServer> server_;
  Client client_;
};

// Lengths given in metres cross the wire with their value in d.
TEST(ResultCodecTest, UserLengthsCrossTheWire) {
  RegistrationResult result;
  result.scales.mls_radius = 0.004;
  result.scales.user_lengths = {{"filter.max_distance_d", 1.0, 38.5}, {"mls.radius_d", 0.004, 0.2}};
  v1::Result proto;
  wire::ToProto(result, &proto);
  ASSERT_EQ(proto.scales().user_lengths_size(), 2);
  EXPECT_EQ(proto.scales().user_lengths(0).parameter(), "filter.max_distance_d");
  const RegistrationResult back = wire::FromProto(proto);
  ASSERT_EQ(back.scales.user_lengths.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(back.scales.user_lengths[i].parameter, result.scales.user_lengths[i].parameter);
    EXPECT_EQ(back.scales.user_lengths[i].value, result.scales.user_lengths[i].value);
    EXPECT_EQ(back.scales.user_lengths[i].value_d, result.scales.user_lengths[i].value_d);
  }
  EXPECT_EQ(back.scales.mls_radius, 0.004);
}

// The target's sensor, the samples hidden from it, and the sides the two sensors saw the inliers
// from cross the wire; a target without a sensor has none after the trip.
TEST(ResultCodecTest, TheSensorAndTheHiddenSamplesCrossTheWire) {
  RegistrationResult result;
  result.verification = VerificationScore{};
  EXPECT_FALSE(wire::FromProto([&] {
                 v1::Result proto;
                 wire::ToProto(result, &proto);
                 return proto;
               }())
                   .scales.sensor.has_value());
  result.scales.sensor = Vec3(1.5, -2.0, 0.25);
  result.verification->samples = 5280;
  result.verification->covered = 3012;
  result.verification->hidden = 2136;
  result.verification->sides_judged = 419;
  result.verification->seen_from_behind = 353;
  result.verification->verdict = Verdict::kSeenFromBehind;
  v1::Result proto;
  wire::ToProto(result, &proto);
  const RegistrationResult back = wire::FromProto(proto);
  ASSERT_TRUE(back.scales.sensor.has_value());
  EXPECT_EQ(*back.scales.sensor, Vec3(1.5, -2.0, 0.25));
  ASSERT_TRUE(back.verification.has_value());
  EXPECT_EQ(back.verification->hidden, 2136);
  EXPECT_EQ(back.verification->sides_judged, 419);
  EXPECT_EQ(back.verification->seen_from_behind, 353);
  EXPECT_EQ(back.verification->verdict, Verdict::kSeenFromBehind);
  EXPECT_DOUBLE_EQ(back.verification->visible_covered_fraction(), 3012.0 / (5280 - 2136));
}

// The weakest translation the rival search probes crosses the wire with its strength.
TEST(ResultCodecTest, TheWeakestTranslationCrossesTheWire) {
  RegistrationResult result;
  result.verification = VerificationScore{};
  result.verification->weakest_translation = Vec3(0.6, -0.8, 0.0);
  result.verification->weakest_translation_strength = 0.0116;
  v1::Result proto;
  wire::ToProto(result, &proto);
  const RegistrationResult back = wire::FromProto(proto);
  ASSERT_TRUE(back.verification.has_value());
  EXPECT_EQ(back.verification->weakest_translation, Vec3(0.6, -0.8, 0.0));
  EXPECT_DOUBLE_EQ(back.verification->weakest_translation_strength, 0.0116);
}

// The pose covariance crosses the wire entry for entry (row-major), with its extent; a score
// without one (a direction without evidence) has none after the trip.
TEST(ResultCodecTest, ThePoseCovarianceCrossesTheWire) {
  RegistrationResult result;
  result.verification = VerificationScore{};
  const auto round_trip = [](const RegistrationResult& r) {
    v1::Result proto;
    wire::ToProto(r, &proto);
    return wire::FromProto(proto);
  };
  EXPECT_FALSE(round_trip(result).verification->pose_covariance.has_value());
  Eigen::Matrix<double, 6, 6> covariance;
  for (int k = 0; k < 36; ++k) covariance(k / 6, k % 6) = 1e-6 * (k + 1);
  result.verification->pose_covariance = covariance;
  result.verification->pose_rotation_sigma_deg = 0.0066;
  result.verification->pose_translation_sigma = 0.0032;
  const RegistrationResult back = round_trip(result);
  ASSERT_TRUE(back.verification->pose_covariance.has_value());
  EXPECT_EQ(*back.verification->pose_covariance, covariance);
  EXPECT_EQ(back.verification->pose_rotation_sigma_deg, 0.0066);
  EXPECT_EQ(back.verification->pose_translation_sigma, 0.0032);
}

// An ambiguous result's rival crosses the wire with its pose, origin and score; a result without
// one has none after the trip.
TEST(ResultCodecTest, TheRivalCrossesTheWire) {
  RegistrationResult result;
  EXPECT_FALSE(wire::FromProto([&] {
                 v1::Result proto;
                 wire::ToProto(result, &proto);
                 return proto;
               }())
                   .rival.has_value());
  AutoCandidate rival;
  rival.origin = CandidateOrigin::kRival;
  rival.refined(0, 3) = 2.0;
  rival.iterations = 11;
  rival.score.verdict = Verdict::kPulled;
  rival.score.inliers = 3149;
  result.rival = rival;
  v1::Result proto;
  wire::ToProto(result, &proto);
  EXPECT_EQ(proto.rival().origin(), v1::CANDIDATE_ORIGIN_RIVAL);
  const RegistrationResult back = wire::FromProto(proto);
  ASSERT_TRUE(back.rival.has_value());
  EXPECT_EQ(back.rival->origin, CandidateOrigin::kRival);
  EXPECT_EQ(back.rival->refined(0, 3), 2.0);
  EXPECT_EQ(back.rival->iterations, 11);
  EXPECT_EQ(back.rival->score.verdict, Verdict::kPulled);
  EXPECT_EQ(back.rival->score.inliers, 3149);
}

TEST_F(RegistrationServiceTest, ResultIsBitIdenticalToTheLibraryAndProgressStreams) {
  ASSERT_NO_FATAL_FAILURE(StartWith(TestConfig()));
  const Matrix4 initial = PerturbedStart(5.0, 5.0, 7);
  const Matrix4& truth = Bun000ToBun045();
  RegistrationOptions options;  // the library defaults (paper Table 2), seed 1
  options.seed = 42;

  // Source in 256 KiB chunks, so the payload really arrives in pieces.
  auto messages = RegisterMessages("bun045", Bun000(), options, initial, truth, 256 << 10);
  ASSERT_GE(messages.size(), 4u);
  messages[0].mutable_header()->set_request_id("bit-exact-1");
  const RegisterOutcome outcome = RunRegister(client_, messages);
  ASSERT_TRUE(outcome.status.ok()) << outcome.status.error_message();

  auto local = Register(*Bun045Target(), Bun000(), initial, options);
  ASSERT_TRUE(local.ok()) << local.status();

  // Accepted first, Result last, Progress in between with increasing iteration numbers.
  ASSERT_GE(outcome.responses.size(), 4u);
  ASSERT_TRUE(outcome.responses.front().has_accepted());
  EXPECT_EQ(outcome.responses.front().accepted().request_id(), "bit-exact-1");
  EXPECT_EQ(outcome.responses.front().accepted().queue_position(), 0);
  ASSERT_TRUE(outcome.responses.back().has_result());
  const std::vector<const v1::Progress*> progress = outcome.progress();
  ASSERT_GE(progress.size(), 2u);
  for (std::size_t i = 1; i < progress.size(); ++i) {
    EXPECT_GT(progress[i]->iteration(), progress[i - 1]->iteration());
  }
  // The last iteration is always delivered, coalescing or not.
  EXPECT_EQ(progress.back()->iteration(), local->iterations);
  EXPECT_TRUE(FromWire(progress.back()->transform()) == local->transform);
  EXPECT_EQ(progress.back()->counts().matched(), local->trace.back().counts.matched);

  const v1::Result& result = *outcome.result();
  const Matrix4 served = FromWire(result.transform());
  for (int i = 0; i < 16; ++i) {
    EXPECT_EQ(served(i / 4, i % 4), local->transform(i / 4, i % 4)) << "element " << i;
  }
  EXPECT_EQ(result.iterations(), local->iterations);
  EXPECT_EQ(result.termination(), wire::TerminationToProto(local->termination));
  EXPECT_EQ(result.converged(), local->converged);
  EXPECT_EQ(result.num_samples(), local->num_samples);
  EXPECT_EQ(result.sampling_distance(), local->sampling_distance);
  EXPECT_GE(result.timings().queue_seconds(), 0.0);
  EXPECT_GT(result.timings().registration_seconds(), 0.0);
  ASSERT_TRUE(result.has_ground_truth_error());
  EXPECT_TRUE(result.ground_truth_error().success());
  EXPECT_LT(result.ground_truth_error().rmse_d(), 2.0);
  EXPECT_LT(result.ground_truth_error().rotation_error_deg(), 1.0);

  v1::Target target;
  ASSERT_TRUE(GetTarget(client_, "bun045", &target).ok());
  EXPECT_EQ(target.registrations(), 1u);
}

TEST_F(RegistrationServiceTest, InlineSourceAndDefaultsWork) {
  ASSERT_NO_FATAL_FAILURE(StartWith(TestConfig()));
  // Method and parameters left unset: auto with the library defaults; no request id given.
  auto messages = RegisterMessages("bun045", Bun000(), QuickOptions(), PerturbedStart(5, 5, 3));
  messages[0].mutable_header()->clear_parameters();
  messages[0].mutable_header()->set_method(v1::METHOD_UNSPECIFIED);
  messages[0].mutable_header()->mutable_parameters()->set_num_samples(500);
  const RegisterOutcome outcome = RunRegister(client_, messages);
  ASSERT_TRUE(outcome.status.ok()) << outcome.status.error_message();
  ASSERT_NE(outcome.accepted(), nullptr);
  EXPECT_EQ(outcome.accepted()->request_id().rfind("req-", 0), 0u);
  ASSERT_NE(outcome.result(), nullptr);
  // The bunny's scans are clean: the verified voxel alignment went straight to the plane-to-plane
  // finish, which polished it over every source point, up to kFinishMaxSamples, and the result
  // counts those.
  std::vector<v1::Stage> stages;
  for (const v1::Progress* p : outcome.progress()) {
    if (stages.empty() || stages.back() != p->stage()) stages.push_back(p->stage());
  }
  EXPECT_EQ(stages, (std::vector<v1::Stage>{v1::STAGE_COARSE, v1::STAGE_FINISH}));
  EXPECT_EQ(outcome.result()->num_samples(), kFinishMaxSamples);
  EXPECT_EQ(outcome.result()->auto_report().finish().samples(), kFinishMaxSamples);
  EXPECT_FALSE(outcome.result()->has_ground_truth_error());
  ASSERT_TRUE(outcome.result()->has_auto_report());  // unspecified is auto
  EXPECT_TRUE(outcome.result()->auto_report().verified());

  // Without the finish the MLS-SICP refinement runs, on the 500 samples asked for.
  messages[0].mutable_header()->mutable_parameters()->set_auto_finish(false);
  const RegisterOutcome refined = RunRegister(client_, messages);
  ASSERT_TRUE(refined.status.ok()) << refined.status.error_message();
  int refinement_reports = 0;
  for (const v1::Progress* p : refined.progress()) {
    if (p->stage() != v1::STAGE_START) continue;
    const v1::CorrespondenceCounts& c = p->counts();
    EXPECT_EQ(c.matched() + c.rejected_normal() + c.rejected_curvature() + c.rejected_distance() +
                  c.invalid(),
              500);
    ++refinement_reports;
  }
  EXPECT_GT(refinement_reports, 0);
  ASSERT_NE(refined.result(), nullptr);
  EXPECT_EQ(refined.result()->num_samples(), 500);
}

// Method auto over the wire from a half-turned start: the stages stream in order, and the result
// carries every candidate, the winner and the verification, as the library computes them.
TEST_F(RegistrationServiceTest, AutoFromAHalfTurnStreamsItsStagesAndReportsItsCandidates) {
  ASSERT_NO_FATAL_FAILURE(StartWith(TestConfig()));
  const Matrix4 initial = PerturbedStart(180.0, 30.0, 2);
  RegistrationOptions options;
  ASSERT_EQ(options.method, Method::kAuto);
  auto messages = RegisterMessages("bun045", Bun000(), options, initial, Bun000ToBun045());
  const RegisterOutcome outcome = RunRegister(client_, messages);
  ASSERT_TRUE(outcome.status.ok()) << outcome.status.error_message();
  auto local = Register(*Bun045Target(), Bun000(), initial, options);
  ASSERT_TRUE(local.ok()) << local.status();
  ASSERT_TRUE(local->auto_report.has_value());

  std::vector<v1::Stage> stages;
  for (const v1::Progress* p : outcome.progress()) {
    if (stages.empty() || stages.back() != p->stage()) stages.push_back(p->stage());
  }
  ASSERT_GE(stages.size(), 4u);
  EXPECT_EQ(stages[0], v1::STAGE_COARSE);
  EXPECT_EQ(stages[1], v1::STAGE_START);
  EXPECT_NE(std::find(stages.begin(), stages.end(), v1::STAGE_GLOBAL), stages.end());
  // The chosen candidate's voxel alignment verified and went straight to the plane-to-plane
  // finish (clean scans).
  EXPECT_EQ(stages[stages.size() - 2], v1::STAGE_CANDIDATE);
  EXPECT_EQ(stages.back(), v1::STAGE_FINISH);

  const v1::Result& result = *outcome.result();
  ASSERT_TRUE(result.has_auto_report());
  const v1::AutoReport& report = result.auto_report();
  EXPECT_TRUE(report.verified());
  EXPECT_FALSE(report.early_exit());
  EXPECT_EQ(report.chosen(), local->auto_report->chosen);
  // The finish that polished the verified pose crosses the wire as run in process.
  EXPECT_EQ(report.finish().kind(), local->auto_report->finish.kind == FinishKind::kPlaneToPlane
                                        ? v1::FINISH_KIND_PLANE_TO_PLANE
                                        : v1::FINISH_KIND_MLS);
  EXPECT_TRUE(report.finish().kept());
  EXPECT_EQ(report.finish().samples(), local->auto_report->finish.samples);
  EXPECT_DOUBLE_EQ(report.finish().noise_sigma_d(), local->auto_report->finish.noise_d);
  ASSERT_EQ(report.candidates_size(), static_cast<int>(local->auto_report->candidates.size()));
  EXPECT_EQ(report.candidates(0).origin(), v1::CANDIDATE_ORIGIN_START);
  EXPECT_EQ(report.candidates(report.chosen()).origin(), v1::CANDIDATE_ORIGIN_GLOBAL);
  for (int k = 0; k < report.candidates_size(); ++k) {
    EXPECT_EQ(report.candidates(k).in_start_basin(),
              local->auto_report->candidates[k].in_start_basin);
  }
  EXPECT_DOUBLE_EQ(report.verification().inlier_fraction(),
                   local->auto_report->verification.inlier_fraction);
  EXPECT_GT(report.global_seconds(), 0.0);
  EXPECT_TRUE(FromWire(result.transform()) == local->transform);
  ASSERT_TRUE(result.has_ground_truth_error());
  EXPECT_TRUE(result.ground_truth_error().success());
  EXPECT_LT(result.ground_truth_error().rotation_error_deg(), 0.5);
}

TEST_F(RegistrationServiceTest, BadRequestsNameTheFieldWhileAGoodOneRuns) {
  ASSERT_NO_FATAL_FAILURE(StartWith(TestConfig()));
  RegistrationOptions long_enough = QuickOptions();
  long_enough.max_iterations = 60;
  long_enough.convergence_d = 0.0;  // exactly 60 iterations
  long_enough.coarse_convergence_d = 0.0;
  long_enough.stall_d = 0.0;
  long_enough.stall_noise_fraction = 0.0;
  long_enough.stall_standard_errors = 0.0;
  RegisterCall good(client_, RegisterMessages("bun045", Bun000(), long_enough,
                                              PerturbedStart(5, 5, 4), Bun000ToBun045()));
  ASSERT_TRUE(good.WaitForAccepted());

  const PointCloud source = Prefix(Bun000(), 5000);
  const Matrix4 start = PerturbedStart(5, 5, 5);
  const auto valid = RegisterMessages("bun045", source, QuickOptions(), start);
  const auto chunked = RegisterMessages("bun045", source, QuickOptions(), start, {}, 32 << 10);
  auto run = [&](const std::vector<v1::RegisterRequest>& m) {
    return RunRegister(client_, m).status;
  };
  int bad = 0;

  {  // NaN coordinate
    PointCloud nan = source;
    nan.points[7].z() = std::numeric_limits<double>::quiet_NaN();
    EXPECT_STATUS(run(RegisterMessages("bun045", nan, QuickOptions(), start)),
                  grpc::StatusCode::INVALID_ARGUMENT, "source.points[7]");
    ++bad;
  }
  {  // Inf coordinate, chunked
    PointCloud inf = source;
    inf.points[4000].x() = std::numeric_limits<double>::infinity();
    EXPECT_STATUS(run(RegisterMessages("bun045", inf, QuickOptions(), start, {}, 32 << 10)),
                  grpc::StatusCode::INVALID_ARGUMENT, "source.points[4000]");
    ++bad;
  }
  {  // zero points
    auto m = valid;
    m[0].mutable_header()->mutable_source()->set_point_count(0);
    m[0].mutable_header()->clear_source_data();
    EXPECT_STATUS(run(m), grpc::StatusCode::INVALID_ARGUMENT, "header.source.point_count");
    ++bad;
  }
  {  // too few points for a registration
    EXPECT_STATUS(run(RegisterMessages("bun045", Prefix(source, 2), QuickOptions(), start)),
                  grpc::StatusCode::INVALID_ARGUMENT, "header.source.point_count");
    ++bad;
  }
  {  // declared count does not match the inline bytes
    auto m = valid;
    m[0].mutable_header()->mutable_source()->set_point_count(source.size() + 1);
    EXPECT_STATUS(run(m), grpc::StatusCode::INVALID_ARGUMENT, "header.source_data");
    ++bad;
  }
  {  // chunks out of order
    auto m = chunked;
    std::swap(m[1], m[2]);
    EXPECT_STATUS(run(m), grpc::StatusCode::INVALID_ARGUMENT, "source_chunk.offset");
    ++bad;
  }
  {  // a chunk above max_chunk_bytes (4 MiB): declare a cloud big enough to need it
    auto m = valid;
    m[0].mutable_header()->mutable_source()->set_point_count(300'000);
    m[0].mutable_header()->clear_source_data();
    m.resize(2);
    m[1].mutable_source_chunk()->set_offset(0);
    m[1].mutable_source_chunk()->set_data(std::string(5 << 20, '\0'));
    EXPECT_STATUS(run(m), grpc::StatusCode::INVALID_ARGUMENT, "source_chunk.data");
    ++bad;
  }
  {  // the stream ends before the declared source is complete
    auto m = chunked;
    m.pop_back();
    EXPECT_STATUS(run(m), grpc::StatusCode::INVALID_ARGUMENT, "source_chunk");
    ++bad;
  }
  {  // unknown method value
    auto m = valid;
    m[0].mutable_header()->set_method(static_cast<v1::Method>(99));
    EXPECT_STATUS(run(m), grpc::StatusCode::INVALID_ARGUMENT, "method");
    ++bad;
  }
  {  // parameter out of range
    auto m = valid;
    m[0].mutable_header()->mutable_parameters()->set_num_samples(1);
    EXPECT_STATUS(run(m), grpc::StatusCode::INVALID_ARGUMENT, "parameters.num_samples");
    ++bad;
  }
  {  // another parameter out of range
    auto m = valid;
    m[0].mutable_header()->mutable_parameters()->set_mls_radius_d(-1.0);
    EXPECT_STATUS(run(m), grpc::StatusCode::INVALID_ARGUMENT, "parameters.mls_radius_d");
    ++bad;
  }
  {  // the damping and stall stop travel too, and are validated
    auto m = valid;
    m[0].mutable_header()->mutable_parameters()->set_tangential_damping(-1.0);
    EXPECT_STATUS(run(m), grpc::StatusCode::INVALID_ARGUMENT, "parameters.tangential_damping");
    ++bad;
    m = valid;
    m[0].mutable_header()->mutable_parameters()->set_stall_d(1e9);
    EXPECT_STATUS(run(m), grpc::StatusCode::INVALID_ARGUMENT, "parameters.stall_d");
    ++bad;
    m = valid;
    m[0].mutable_header()->mutable_parameters()->set_coarse_phase_filters(
        static_cast<v1::CoarsePhaseFilters>(42));
    EXPECT_STATUS(run(m), grpc::StatusCode::INVALID_ARGUMENT, "parameters.coarse_phase_filters");
    ++bad;
  }
  {  // non-rigid initial transform (scaled)
    Matrix4 scaled = start;
    scaled.topLeftCorner<3, 3>() *= 2.0;
    EXPECT_STATUS(run(RegisterMessages("bun045", source, QuickOptions(), scaled)),
                  grpc::StatusCode::INVALID_ARGUMENT, "header.initial_transform");
    ++bad;
  }
  {  // non-rigid ground truth (sheared)
    Matrix4 sheared = Bun000ToBun045();
    sheared(0, 1) += 0.3;
    EXPECT_STATUS(run(RegisterMessages("bun045", source, QuickOptions(), start, sheared)),
                  grpc::StatusCode::INVALID_ARGUMENT, "header.ground_truth");
    ++bad;
  }
  {  // bad target id
    EXPECT_STATUS(run(RegisterMessages("bun 045/../x", source, QuickOptions(), start)),
                  grpc::StatusCode::INVALID_ARGUMENT, "header.target_id");
    ++bad;
  }
  {  // the first message is a chunk
    auto m = chunked;
    m.erase(m.begin());
    EXPECT_STATUS(run(m), grpc::StatusCode::INVALID_ARGUMENT, "header");
    ++bad;
  }
  // Unknown target: NOT_FOUND, answered before the source is sent.
  EXPECT_STATUS(
      run(RegisterMessages("no-such-target", source, QuickOptions(), start, {}, 32 << 10)),
      grpc::StatusCode::NOT_FOUND, "no-such-target");

  const RegisterOutcome outcome = good.Join();
  ASSERT_TRUE(outcome.status.ok()) << outcome.status.error_message();
  ASSERT_NE(outcome.result(), nullptr);
  EXPECT_EQ(outcome.result()->iterations(), 60);
  EXPECT_TRUE(outcome.result()->ground_truth_error().success());

  // Every bad request was refused before admission: only the good one reached a worker.
  const v1::GetStatsResponse stats = Stats(client_);
  std::map<std::string, std::uint64_t> register_codes;
  for (const auto& c : stats.requests()) {
    if (c.rpc() == "Register") register_codes[c.code()] = c.count();
  }
  EXPECT_EQ(register_codes["INVALID_ARGUMENT"], static_cast<std::uint64_t>(bad));
  EXPECT_EQ(register_codes["NOT_FOUND"], 1u);
  EXPECT_EQ(register_codes["OK"], 1u);
  v1::Target target;
  ASSERT_TRUE(GetTarget(client_, "bun045", &target).ok());
  EXPECT_EQ(target.registrations(), 1u);
}

TEST_F(RegistrationServiceTest, CancellationFreesTheWorkerAtOnce) {
  ServerConfig config = TestConfig();
  config.workers = 1;
  ASSERT_NO_FATAL_FAILURE(StartWith(config));
  {
    RegisterCall endless(
        client_, RegisterMessages("bun045", Bun000(), EndlessOptions(), PerturbedStart(5, 5, 6)));
    ASSERT_TRUE(endless.WaitForProgress(1));
    EXPECT_EQ(active_jobs(), 1);
    endless.Cancel();
    EXPECT_EQ(endless.Join().status.error_code(), grpc::StatusCode::CANCELLED);
  }
  EXPECT_TRUE(Eventually([&] { return active_jobs() == 0; }, std::chrono::seconds(1)));
  // The only worker is free: the next registration runs.
  const RegisterOutcome next = RunRegister(
      client_, RegisterMessages("bun045", Bun000(), QuickOptions(), PerturbedStart(5, 5, 8)));
  ASSERT_TRUE(next.status.ok()) << next.status.error_message();
  EXPECT_NE(next.result(), nullptr);
}

// A cancel ends the call (Finish) on one of gRPC's threads while the worker's progress starts
// the next write: no write may start after Finish, or its completion reaches a freed reactor
// (it aborted the server with "pure virtual method called", about once in a thousand cancels
// under load). Many cancels racing a stream of progress, then the server still serves.
TEST_F(RegistrationServiceTest, CancelsRacingProgressWritesLeaveTheServerServing) {
  ServerConfig config = TestConfig();
  config.workers = 2;
  ASSERT_NO_FATAL_FAILURE(StartWith(config));
  for (std::uint64_t round = 0; round < 16; ++round) {
    RegisterCall first(client_, RegisterMessages("bun045", Bun000(), EndlessOptions(),
                                                 PerturbedStart(5, 5, 100 + 2 * round)));
    RegisterCall second(client_, RegisterMessages("bun045", Bun000(), EndlessOptions(),
                                                  PerturbedStart(5, 5, 101 + 2 * round)));
    ASSERT_TRUE(first.WaitForProgress(1));
    ASSERT_TRUE(second.WaitForProgress(1));
    first.Cancel();
    second.Cancel();
    EXPECT_EQ(first.Join().status.error_code(), grpc::StatusCode::CANCELLED);
    EXPECT_EQ(second.Join().status.error_code(), grpc::StatusCode::CANCELLED);
  }
  EXPECT_TRUE(Eventually([&] { return active_jobs() == 0; }, std::chrono::seconds(2)));
  const RegisterOutcome next = RunRegister(
      client_, RegisterMessages("bun045", Bun000(), QuickOptions(), PerturbedStart(5, 5, 8)));
  ASSERT_TRUE(next.status.ok()) << next.status.error_message();
  EXPECT_NE(next.result(), nullptr);
}

TEST_F(RegistrationServiceTest, DeadlineStopsTheRegistration) {
  ServerConfig config = TestConfig();
  config.workers = 1;
  ASSERT_NO_FATAL_FAILURE(StartWith(config));
  const auto start = std::chrono::steady_clock::now();
  const RegisterOutcome outcome = RunRegister(
      client_, RegisterMessages("bun045", Bun000(), EndlessOptions(), PerturbedStart(5, 5, 9)),
      std::chrono::milliseconds(700));
  EXPECT_EQ(outcome.status.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED);
  EXPECT_GE(outcome.progress_count(), 1);  // it did run
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  EXPECT_TRUE(Eventually([&] { return active_jobs() == 0; }, std::chrono::seconds(1)));
}

TEST_F(RegistrationServiceTest, FullQueueIsResourceExhausted) {
  ServerConfig config = TestConfig();
  config.workers = 1;
  config.queue_capacity = 1;
  ASSERT_NO_FATAL_FAILURE(StartWith(config));
  auto endless = [&](std::uint64_t seed) {
    return RegisterMessages("bun045", Bun000(), EndlessOptions(), PerturbedStart(5, 5, seed));
  };
  RegisterCall running(client_, endless(10));
  ASSERT_TRUE(running.WaitForProgress(1));
  RegisterCall queued(client_, endless(11));
  ASSERT_TRUE(queued.WaitForAccepted());
  EXPECT_EQ(Stats(client_).queue_depth(), 1);

  const RegisterOutcome refused = RunRegister(client_, endless(12));
  EXPECT_STATUS(refused.status, grpc::StatusCode::RESOURCE_EXHAUSTED,
                "job queue full (capacity 1)");
  EXPECT_EQ(refused.accepted(), nullptr);

  running.Cancel();
  queued.Cancel();
  EXPECT_EQ(running.Join().status.error_code(), grpc::StatusCode::CANCELLED);
  EXPECT_EQ(queued.Join().status.error_code(), grpc::StatusCode::CANCELLED);
  EXPECT_TRUE(Eventually(
      [&] {
        const v1::GetStatsResponse s = Stats(client_);
        return s.active_jobs() == 0 && s.queue_depth() == 0;
      },
      std::chrono::seconds(2)));
}

}  // namespace
}  // namespace mlsreg::service_test
