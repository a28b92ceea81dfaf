#include "common/tracking/forest_training.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <random>
#include <thread>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace reenact::tracking {
namespace {

struct Sample {
  int32_t image = 0;
  int16_t x = 0, y = 0;
  uint8_t part = 0;
  float z_m = 0;
  Eigen::Vector3f point_m = Eigen::Vector3f::Zero();  // Camera frame.
};

using Histogram = std::vector<int64_t>;

double Entropy(const int64_t* counts, int num_parts, int64_t total) {
  if (total <= 0) return 0;
  double h = 0;
  for (int p = 0; p < num_parts; ++p) {
    if (counts[p] == 0) continue;
    const double q = static_cast<double>(counts[p]) / total;
    h -= q * std::log2(q);
  }
  return h;
}

class TreeTrainer {
 public:
  TreeTrainer(const std::vector<TrainingImage>& images, const ForestTrainingOptions& options,
              int num_parts, uint64_t seed, std::atomic<int64_t>* samples_done,
              const std::atomic<bool>* cancel)
      : images_(images),
        o_(options),
        num_parts_(num_parts),
        rng_(seed),
        samples_done_(samples_done),
        cancel_(cancel) {
    for (const TrainingImage& image : images) {
      probes_.push_back(DepthProbe{image.depth_m.data.data(), image.depth_m.width,
                                   image.depth_m.height, static_cast<float>(image.intrinsics.fx),
                                   static_cast<float>(image.intrinsics.fy)});
    }
  }

  DecisionTree Train() {
    DrawSamples();
    Build(0, samples_.size(), 0);
    return std::move(tree_);
  }
  size_t num_samples() const { return samples_.size(); }

 private:
  void DrawSamples() {
    for (size_t i = 0; i < images_.size(); ++i) {
      const TrainingImage& image = images_[i];
      std::vector<int> on_person;
      for (size_t p = 0; p < image.part.size(); ++p) {
        if (image.part[p] != kNoPart) on_person.push_back(static_cast<int>(p));
      }
      std::shuffle(on_person.begin(), on_person.end(), rng_);
      on_person.resize(std::min<size_t>(on_person.size(), o_.pixels_per_image));
      for (int p : on_person) samples_.push_back(MakeSample(static_cast<int>(i), p));
    }
  }

  Sample MakeSample(int image_index, int pixel) const {
    const TrainingImage& image = images_[static_cast<size_t>(image_index)];
    const CameraIntrinsics& k = image.intrinsics;
    Sample s;
    s.image = image_index;
    s.x = static_cast<int16_t>(pixel % image.depth_m.width);
    s.y = static_cast<int16_t>(pixel / image.depth_m.width);
    s.part = image.part[static_cast<size_t>(pixel)];
    s.z_m = image.depth_m.data[static_cast<size_t>(pixel)];
    s.point_m = Eigen::Vector3f(static_cast<float>((s.x - k.cx) / k.fx) * s.z_m,
                                static_cast<float>((s.y - k.cy) / k.fy) * s.z_m, s.z_m);
    return s;
  }

  float Evaluate(const SplitFeature& f, const Sample& s) const {
    return probes_[static_cast<size_t>(s.image)].Feature(f, s.x, s.y, s.z_m);
  }

  SplitFeature RandomFeature() {
    std::uniform_real_distribution<float> offset(static_cast<float>(-o_.max_offset_m),
                                                 static_cast<float>(o_.max_offset_m));
    SplitFeature f;
    f.u_x_m = offset(rng_), f.u_y_m = offset(rng_);
    if (std::uniform_real_distribution<double>(0, 1)(rng_) >= o_.unary_fraction) {
      f.v_x_m = offset(rng_), f.v_y_m = offset(rng_);
    }
    return f;
  }

  // The best split of samples_[begin, end): gain and feature (threshold set).
  std::pair<double, SplitFeature> ChooseSplit(size_t begin, size_t end) {
    std::vector<size_t> subset(end - begin);
    for (size_t i = 0; i < subset.size(); ++i) subset[i] = begin + i;
    if (subset.size() > static_cast<size_t>(o_.max_samples_per_split)) {
      std::shuffle(subset.begin(), subset.end(), rng_);
      subset.resize(static_cast<size_t>(o_.max_samples_per_split));
    }
    const int64_t n = static_cast<int64_t>(subset.size());
    Histogram parent(static_cast<size_t>(num_parts_), 0);
    for (size_t i : subset) ++parent[samples_[i].part];
    const double parent_entropy = Entropy(parent.data(), num_parts_, n);
    const int t = o_.thresholds_per_feature;
    std::vector<float> values(subset.size()), thresholds(static_cast<size_t>(t));
    Histogram bins(static_cast<size_t>((t + 1) * num_parts_));
    double best_gain = 0;
    SplitFeature best;
    std::uniform_int_distribution<size_t> pick(0, subset.size() - 1);
    for (int c = 0; c < o_.features_per_node; ++c) {
      SplitFeature f = RandomFeature();
      for (size_t i = 0; i < subset.size(); ++i) values[i] = Evaluate(f, samples_[subset[i]]);
      for (float& th : thresholds) th = values[pick(rng_)];
      std::sort(thresholds.begin(), thresholds.end());
      std::fill(bins.begin(), bins.end(), 0);
      for (size_t i = 0; i < subset.size(); ++i) {
        const int b = static_cast<int>(
            std::upper_bound(thresholds.begin(), thresholds.end(), values[i]) - thresholds.begin());
        ++bins[static_cast<size_t>(b) * static_cast<size_t>(num_parts_) + samples_[subset[i]].part];
      }
      Histogram left(static_cast<size_t>(num_parts_), 0);
      int64_t n_left = 0;
      for (int k = 0; k < t; ++k) {  // Left of threshold k: bins 0..k.
        for (int p = 0; p < num_parts_; ++p) {
          const int64_t c_kp = bins[static_cast<size_t>(k) * static_cast<size_t>(num_parts_) +
                                    static_cast<size_t>(p)];
          left[static_cast<size_t>(p)] += c_kp;
          n_left += c_kp;
        }
        if (n_left == 0 || n_left == n) continue;
        Histogram right(static_cast<size_t>(num_parts_));
        for (int p = 0; p < num_parts_; ++p) right[p] = parent[p] - left[p];
        const double gain =
            parent_entropy -
            (static_cast<double>(n_left) / n) * Entropy(left.data(), num_parts_, n_left) -
            (static_cast<double>(n - n_left) / n) * Entropy(right.data(), num_parts_, n - n_left);
        if (gain > best_gain) {
          best_gain = gain;
          best = f;
          best.threshold_m = thresholds[static_cast<size_t>(k)];
        }
      }
    }
    return {best_gain, best};
  }

  int32_t Build(size_t begin, size_t end, int depth) {
    const size_t n = end - begin;
    if (!*cancel_ && depth < o_.max_depth && n >= 2 * static_cast<size_t>(o_.min_samples_leaf) &&
        !IsPure(begin, end)) {
      const auto [gain, feature] = ChooseSplit(begin, end);
      // A named reference for the lambda (clang before 16 cannot capture a
      // structured binding).
      const SplitFeature& split_on = feature;
      const auto mid = std::stable_partition(
          samples_.begin() + static_cast<std::ptrdiff_t>(begin),
          samples_.begin() + static_cast<std::ptrdiff_t>(end),
          [&](const Sample& s) { return Evaluate(split_on, s) < split_on.threshold_m; });
      const size_t split = static_cast<size_t>(mid - samples_.begin());
      if (gain > 0 && split > begin && split < end) {
        const int32_t index = static_cast<int32_t>(tree_.nodes.size());
        tree_.nodes.push_back(ForestNode{0, 0, -1, feature});
        const int32_t left = Build(begin, split, depth + 1);
        const int32_t right = Build(split, end, depth + 1);
        tree_.nodes[static_cast<size_t>(index)].left = left;
        tree_.nodes[static_cast<size_t>(index)].right = right;
        return index;
      }
    }
    return MakeLeaf(begin, end);
  }

  bool IsPure(size_t begin, size_t end) const {
    for (size_t i = begin + 1; i < end; ++i) {
      if (samples_[i].part != samples_[begin].part) return false;
    }
    return true;
  }

  int32_t MakeLeaf(size_t begin, size_t end) {
    ForestLeaf leaf;
    leaf.part_probability.assign(static_cast<size_t>(num_parts_), 0.0f);
    for (size_t i = begin; i < end; ++i) leaf.part_probability[samples_[i].part] += 1.0f;
    for (float& p : leaf.part_probability) p /= static_cast<float>(end - begin);
    MakeVotes(begin, end, &leaf);
    const int32_t index = static_cast<int32_t>(tree_.nodes.size());
    tree_.nodes.push_back(ForestNode{-1, -1, static_cast<int32_t>(tree_.leaves.size()), {}});
    tree_.leaves.push_back(std::move(leaf));
    samples_done_->fetch_add(static_cast<int64_t>(end - begin));
    return index;
  }

  // Girshick et al. sec. 3.1: per joint, the mode of the offsets within the
  // vote radius, found by mean shift from their mean; its weight is the
  // share of the leaf's pixels within two bandwidths of it.
  void MakeVotes(size_t begin, size_t end, ForestLeaf* leaf) {
    const size_t n = end - begin;
    const size_t stride = std::max<size_t>(1, n / 400);
    std::vector<JointVote> votes;
    std::vector<Eigen::Vector3f> offsets;
    const float radius = static_cast<float>(o_.vote_radius_m);
    const float b = static_cast<float>(o_.vote_bandwidth_m);
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      offsets.clear();
      for (size_t i = begin; i < end; i += stride) {
        const Sample& s = samples_[i];
        const Eigen::Vector3f o =
            images_[static_cast<size_t>(s.image)].joints_in_camera_m[j].cast<float>() - s.point_m;
        if (o.norm() < radius) offsets.push_back(o);
      }
      if (offsets.empty()) continue;
      Eigen::Vector3f mode = Eigen::Vector3f::Zero();
      for (const auto& o : offsets) mode += o;
      mode /= static_cast<float>(offsets.size());
      for (int it = 0; it < 8; ++it) {
        Eigen::Vector3f sum = Eigen::Vector3f::Zero();
        float weight = 0;
        for (const auto& o : offsets) {
          const float w = std::exp(-(o - mode).squaredNorm() / (2 * b * b));
          sum += w * o;
          weight += w;
        }
        if (weight < 1e-6f) break;
        mode = sum / weight;
      }
      int support = 0;
      for (const auto& o : offsets) support += (o - mode).norm() < 2 * b ? 1 : 0;
      const float share = static_cast<float>(support) * stride / static_cast<float>(n);
      if (share > 0.05f)
        votes.push_back(JointVote{static_cast<uint8_t>(j), std::min(share, 1.0f), mode});
    }
    std::sort(votes.begin(), votes.end(),
              [](const JointVote& a, const JointVote& b) { return a.weight > b.weight; });
    for (size_t k = 0; k < votes.size() && k < leaf->votes.size(); ++k) leaf->votes[k] = votes[k];
  }

  const std::vector<TrainingImage>& images_;
  const ForestTrainingOptions& o_;
  const int num_parts_;
  std::mt19937_64 rng_;
  std::atomic<int64_t>* samples_done_;
  const std::atomic<bool>* cancel_;
  std::vector<DepthProbe> probes_;
  std::vector<Sample> samples_;
  DecisionTree tree_;
};

}  // namespace

absl::Status ForestTrainingOptions::Validate() const {
  if (num_trees < 1 || num_trees > 16) return absl::InvalidArgumentError("trees must be 1..16");
  if (max_depth < 1 || max_depth > 40) return absl::InvalidArgumentError("depth must be 1..40");
  if (min_samples_leaf < 1 || pixels_per_image < 1 || features_per_node < 1 ||
      thresholds_per_feature < 1 || max_samples_per_split < 10) {
    return absl::InvalidArgumentError("training counts must be positive");
  }
  if (!(max_offset_m > 0 && max_offset_m < 2.0)) {
    return absl::InvalidArgumentError("feature offsets must be within (0, 2) m");
  }
  if (!(vote_radius_m > 0 && vote_bandwidth_m > 0) ||
      !(unary_fraction >= 0 && unary_fraction <= 1)) {
    return absl::InvalidArgumentError("vote radius and bandwidth must be > 0");
  }
  return absl::OkStatus();
}

absl::StatusOr<BodyPartForest> TrainForest(const std::vector<TrainingImage>& images,
                                           const ForestTrainingOptions& options,
                                           const std::string& description,
                                           ForestTrainingSummary* summary,
                                           const ProgressCallback& progress) {
  RETURN_IF_ERROR(options.Validate());
  if (images.empty()) return absl::InvalidArgumentError("no training images");
  const auto start = std::chrono::steady_clock::now();
  const int num_parts = body::kNumKinectV2Joints;
  std::vector<DecisionTree> trees(static_cast<size_t>(options.num_trees));
  std::atomic<int64_t> samples_done{0}, samples_per_tree{0};
  std::atomic<int> next_tree{0}, finished{0};
  std::atomic<bool> cancel{false};
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int threads = std::min(options.num_trees, options.threads > 0 ? options.threads : cores);
  std::vector<std::thread> workers;
  workers.reserve(static_cast<size_t>(threads));
  for (int w = 0; w < threads; ++w) {
    workers.emplace_back([&] {
      for (int t = next_tree++; t < options.num_trees; t = next_tree++) {
        TreeTrainer trainer(images, options, num_parts,
                            options.seed * 1000003u + static_cast<uint64_t>(t), &samples_done,
                            &cancel);
        trees[static_cast<size_t>(t)] = trainer.Train();
        samples_per_tree = static_cast<int64_t>(trainer.num_samples());
        ++finished;
      }
    });
  }
  const int64_t expected =
      static_cast<int64_t>(images.size()) * options.pixels_per_image * options.num_trees;
  while (finished < options.num_trees) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    const double f =
        std::min(1.0, static_cast<double>(samples_done) / static_cast<double>(expected));
    if (progress && !cancel && !progress(Progress{"train", f, samples_done, expected})) {
      cancel = true;
    }
  }
  for (auto& w : workers) w.join();
  if (cancel) return absl::CancelledError("forest training cancelled");
  BodyPartForest forest(num_parts, std::move(trees), description);
  RETURN_IF_ERROR(forest.Validate());
  if (summary) {
    summary->samples = samples_per_tree;
    summary->nodes = forest.num_nodes();
    summary->leaves = 0;
    for (const DecisionTree& t : forest.trees())
      summary->leaves += static_cast<int64_t>(t.leaves.size());
    summary->max_depth = forest.max_depth();
    summary->seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return forest;
}

}  // namespace reenact::tracking
