#include "mlsreg/registration/global_candidates.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include "mlsreg/core/transform.h"
#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg {
namespace {

using Match = std::pair<std::uint32_t, std::uint32_t>;  // (source sample, target sample)

// RANSAC draws from the one-way matches when fewer than this are mutual.
constexpr std::size_t kMinMutual = 30;

double RotationAngleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const double c = std::clamp(((a.transpose() * b).trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) * 180.0 / std::numbers::pi;
}

class Ransac {
 public:
  Ransac(const FeatureCloud& source, const FeatureCloud& target, std::vector<Match> matches,
         const GlobalCandidateOptions& options)
      : source_(source),
        target_(target),
        matches_(std::move(matches)),
        options_(options),
        centre_(Centroid(source.points)) {
    distinct_translation_ = options.distinct_translation > 0.0 ? options.distinct_translation
                                                               : 2.0 * options.inlier_distance;
  }

  // Runs the trials; false when stopped.
  bool Run(const StopCheck& should_stop, int& trials) {
    trials = 0;
    if (matches_.size() < 3) return true;
    std::mt19937_64 rng(options_.seed);
    std::uniform_int_distribution<std::size_t> pick(0, matches_.size() - 1);
    StopPoller stop(should_stop, 512);
    double needed = options_.max_trials;
    for (; trials < options_.max_trials && trials < needed; ++trials) {
      if (stop.Poll()) return false;
      const std::size_t a = pick(rng), b = pick(rng), c = pick(rng);
      if (a == b || b == c || a == c) continue;
      const std::array<std::size_t, 3> triple{a, b, c};
      if (!EdgesAgree(triple)) continue;
      std::array<Vec3, 3> x, y;
      for (int k = 0; k < 3; ++k) {
        x[k] = source_.points[matches_[triple[k]].first];
        y[k] = target_.points[matches_[triple[k]].second];
      }
      const std::array<double, 3> w{1.0, 1.0, 1.0};
      const RigidTransform pose = PointToPointMotion(x, y, w);
      bool close = true;
      for (int k = 0; k < 3 && close; ++k) {
        close = (pose * x[k] - y[k]).squaredNorm() <= Squared(options_.inlier_distance);
      }
      if (!close) continue;
      const int inliers = CountInliers(pose);
      if (Offer(pose, inliers) && inliers == best_inliers()) {
        // Trials needed to draw an all-inlier triple with the given confidence.
        const double ratio = static_cast<double>(inliers) / matches_.size();
        const double miss = 1.0 - ratio * ratio * ratio;
        if (miss <= 0.0) {
          needed = 0;
        } else {
          // Twice that, so that the runners-up are found too.
          needed = 2.0 * std::log(1.0 - options_.confidence) / std::log(miss);
        }
      }
    }
    return true;
  }

  // The kept poses, each refitted to its inliers, best first.
  std::vector<GlobalCandidate> Candidates() const {
    std::vector<GlobalCandidate> out;
    for (const auto& [pose, count] : kept_) {
      std::vector<Vec3> x, y;
      for (const auto& [i, j] : matches_) {
        if ((pose * source_.points[i] - target_.points[j]).squaredNorm() <=
            Squared(options_.inlier_distance)) {
          x.push_back(source_.points[i]);
          y.push_back(target_.points[j]);
        }
      }
      const std::vector<double> w(x.size(), 1.0);
      const RigidTransform refit = x.size() >= 3 ? PointToPointMotion(x, y, w) : pose;
      out.push_back({refit.matrix(), CountInliers(refit)});
    }
    std::stable_sort(out.begin(), out.end(),
                     [](const auto& a, const auto& b) { return a.inliers > b.inliers; });
    return out;
  }

 private:
  static double Squared(double x) { return x * x; }
  int best_inliers() const { return kept_.empty() ? 0 : kept_.front().second; }

  bool EdgesAgree(const std::array<std::size_t, 3>& t) const {
    for (int k = 0; k < 3; ++k) {
      const Match& m = matches_[t[k]];
      const Match& n = matches_[t[(k + 1) % 3]];
      const double ls = (source_.points[m.first] - source_.points[n.first]).norm();
      const double lt = (target_.points[m.second] - target_.points[n.second]).norm();
      if (!(ls > 0.0 && lt > 0.0) || ls < options_.edge_ratio * lt ||
          lt < options_.edge_ratio * ls) {
        return false;
      }
    }
    return true;
  }

  int CountInliers(const RigidTransform& pose) const {
    int inliers = 0;
    const double limit = Squared(options_.inlier_distance);
    for (const auto& [i, j] : matches_) {
      inliers += (pose * source_.points[i] - target_.points[j]).squaredNorm() <= limit;
    }
    return inliers;
  }

  bool Distinct(const RigidTransform& a, const RigidTransform& b) const {
    return RotationAngleDeg(a.linear(), b.linear()) > options_.distinct_rotation_deg ||
           (a * centre_ - b * centre_).norm() > distinct_translation_;
  }

  // Keeps `pose` among the best distinct ones; true when it was kept.
  bool Offer(const RigidTransform& pose, int inliers) {
    if (inliers < 3) return false;
    for (auto& entry : kept_) {
      if (!Distinct(entry.first, pose)) {
        if (inliers <= entry.second) return false;
        entry = {pose, inliers};
        Sort();
        return true;
      }
    }
    if (static_cast<int>(kept_.size()) >= options_.max_candidates) {
      if (inliers <= kept_.back().second) return false;
      kept_.pop_back();
    }
    kept_.emplace_back(pose, inliers);
    Sort();
    return true;
  }

  void Sort() {
    std::stable_sort(kept_.begin(), kept_.end(),
                     [](const auto& a, const auto& b) { return a.second > b.second; });
  }

  const FeatureCloud& source_;
  const FeatureCloud& target_;
  std::vector<Match> matches_;
  const GlobalCandidateOptions& options_;
  Vec3 centre_ = Vec3::Zero();
  double distinct_translation_ = 0.0;
  std::vector<std::pair<RigidTransform, int>> kept_;
};

}  // namespace

FeatureMatches MatchFeatures(const FeatureCloud& source, const FeatureCloud& target,
                             std::size_t min_mutual, const StopCheck& should_stop) {
  FeatureMatches out;
  const std::size_t ns = source.size(), nt = target.size();
  if (ns == 0 || nt == 0) return out;
  constexpr float kInf = std::numeric_limits<float>::max();
  std::vector<std::uint32_t> best_of_source(ns, 0), best_of_target(nt, 0);
  std::vector<float> best_source_d2(ns, kInf), best_target_d2(nt, kInf);
  StopPoller stop(should_stop, 32);  // a row is a pass over all target features
  for (std::uint32_t i = 0; i < ns; ++i) {
    if (stop.Poll()) {
      out.stopped = true;
      return out;
    }
    const FpfhFeature& f = source.features[i];
    for (std::uint32_t j = 0; j < nt; ++j) {
      const FpfhFeature& g = target.features[j];
      float d2 = 0.0f;
      for (int b = 0; b < 33; ++b) {
        const float diff = f[b] - g[b];
        d2 += diff * diff;
      }
      if (d2 < best_source_d2[i]) {
        best_source_d2[i] = d2;
        best_of_source[i] = j;
      }
      if (d2 < best_target_d2[j]) {
        best_target_d2[j] = d2;
        best_of_target[j] = i;
      }
    }
  }
  for (std::uint32_t i = 0; i < ns; ++i) {
    if (best_of_target[best_of_source[i]] == i) out.pairs.emplace_back(i, best_of_source[i]);
  }
  if (out.pairs.size() < min_mutual) {
    out.pairs.clear();
    out.mutual = false;
    for (std::uint32_t i = 0; i < ns; ++i) out.pairs.emplace_back(i, best_of_source[i]);
  }
  return out;
}

GlobalCandidates FindGlobalCandidates(const FeatureCloud& source, const FeatureCloud& target,
                                      const GlobalCandidateOptions& options,
                                      const StopCheck& should_stop) {
  GlobalCandidates out;
  FeatureMatches matched = MatchFeatures(source, target, kMinMutual, should_stop);
  if (matched.stopped) {
    out.stopped = true;
    return out;
  }
  out.matches = static_cast<int>(matched.pairs.size());
  Ransac ransac(source, target, std::move(matched.pairs), options);
  if (!ransac.Run(should_stop, out.trials)) {
    out.stopped = true;
    return out;
  }
  out.candidates = ransac.Candidates();
  return out;
}

}  // namespace mlsreg
