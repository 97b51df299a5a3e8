// Global candidates: poses from FPFH feature matches, independent of any initial pose. Mutual
// nearest neighbours in feature space, then RANSAC over triples of matches with the usual pruning
// (corresponding edges within 10 % of each other, each match of the triple within the inlier
// distance), scored by the share of matches it explains. The best few distinct poses come back,
// each refitted to its inliers, for refinement and verification (registration/verification.h).
#pragma once

#include <cstdint>
#include <vector>

#include "mlsreg/core/stop_check.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/geometry/feature_cloud.h"

namespace mlsreg {

// Feature matches (source sample, target sample): nearest neighbours in feature space both ways
// in one pass over all pairs, keeping the mutual ones; when fewer than `min_mutual` are mutual,
// every source sample's nearest instead (as Open3D does).
struct FeatureMatches {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  bool mutual = true;
  bool stopped = false;  // `should_stop` said stop; pairs are then empty
};
FeatureMatches MatchFeatures(const FeatureCloud& source, const FeatureCloud& target,
                             std::size_t min_mutual, const StopCheck& should_stop = {});

struct GlobalCandidateOptions {
  int max_candidates = 8;
  int max_trials = 50'000;
  double confidence = 0.999;  // early exit once the best pose is this sure to have been drawn
  // Matches within this distance of each other under a pose are its inliers (absolute units).
  double inlier_distance = 0.0;
  double edge_ratio = 0.9;
  // Two poses closer than this (rotation, and translation of the source's centre) are one.
  double distinct_rotation_deg = 10.0;
  double distinct_translation = 0.0;  // absolute; 0: 2 * inlier_distance
  std::uint64_t seed = 1;
};

struct GlobalCandidate {
  Matrix4 transform = Matrix4::Identity();  // source to target
  int inliers = 0;                          // matches it explains
};

struct GlobalCandidates {
  std::vector<GlobalCandidate> candidates;  // best first
  int matches = 0;  // feature matches RANSAC drew from (mutual ones when there are enough)
  int trials = 0;
  bool stopped = false;  // `should_stop` said stop; candidates are then empty
};

GlobalCandidates FindGlobalCandidates(const FeatureCloud& source, const FeatureCloud& target,
                                      const GlobalCandidateOptions& options,
                                      const StopCheck& should_stop = {});

}  // namespace mlsreg
