#include "common/tracking/body_part_forest.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "common/body/joint_set.h"

namespace reenact::tracking {
namespace {

// File layout (little-endian): "RTFOREST", u32 version, u32 num_parts,
// u32 num_trees, u32 description bytes, the description; per tree u32 nodes,
// u32 leaves, the nodes (i32 left, i32 right, i32 leaf, i16 u_x, u_y, v_x,
// v_y in mm, f32 threshold_m), the leaves (u8 P(part) * 255 per part, then
// kMaxLeafVotes x (u8 joint, u8 weight * 255, i16 offset x, y, z in mm)).
constexpr char kMagic[8] = {'R', 'T', 'F', 'O', 'R', 'E', 'S', 'T'};
constexpr uint32_t kVersion = 1;
constexpr size_t kNodeBytes = 3 * 4 + 4 * 2 + 4;
constexpr size_t kVoteBytes = 1 + 1 + 3 * 2;
constexpr uint32_t kMaxParts = 64;
constexpr uint32_t kMaxTrees = 16;

class Writer {
 public:
  template <typename T>
  void Put(T value) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    out_.append(bytes, sizeof(T));
  }
  void PutBytes(const std::string& s) { out_ += s; }
  std::string& out() { return out_; }

 private:
  std::string out_;
};

class Reader {
 public:
  explicit Reader(const std::string& bytes) : bytes_(bytes) {}
  template <typename T>
  bool Get(T* value) {
    if (left() < sizeof(T)) return false;
    std::memcpy(value, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  bool GetBytes(size_t n, std::string* s) {
    if (left() < n) return false;
    s->assign(bytes_.data() + pos_, n);
    pos_ += n;
    return true;
  }
  size_t left() const { return bytes_.size() - pos_; }

 private:
  const std::string& bytes_;
  size_t pos_ = 0;
};

int16_t ToMm(float metres) {
  return static_cast<int16_t>(std::lround(std::clamp(metres * 1000.0f, -32767.0f, 32767.0f)));
}

uint8_t ToByte(float unit) {
  return static_cast<uint8_t>(std::lround(std::clamp(unit, 0.0f, 1.0f) * 255.0f));
}

void WriteTree(const DecisionTree& tree, int num_parts, Writer* w) {
  w->Put(static_cast<uint32_t>(tree.nodes.size()));
  w->Put(static_cast<uint32_t>(tree.leaves.size()));
  for (const ForestNode& n : tree.nodes) {
    w->Put(n.left);
    w->Put(n.right);
    w->Put(n.leaf);
    for (float v : {n.feature.u_x_m, n.feature.u_y_m, n.feature.v_x_m, n.feature.v_y_m}) {
      w->Put(ToMm(v));
    }
    w->Put(n.feature.threshold_m);
  }
  for (const ForestLeaf& leaf : tree.leaves) {
    for (int p = 0; p < num_parts; ++p) w->Put(ToByte(leaf.part_probability[p]));
    for (const JointVote& v : leaf.votes) {
      w->Put(v.joint);
      w->Put(ToByte(v.weight));
      for (int k = 0; k < 3; ++k) w->Put(ToMm(v.offset_m[k]));
    }
  }
}

absl::Status Truncated(const char* what) {
  return absl::DataLossError(absl::StrCat("tracker forest: truncated or corrupt (", what, ")"));
}

absl::Status ReadNode(Reader* r, ForestNode* n) {
  int16_t mm[4];
  if (!r->Get(&n->left) || !r->Get(&n->right) || !r->Get(&n->leaf)) return Truncated("node");
  for (int16_t& v : mm) {
    if (!r->Get(&v)) return Truncated("node");
  }
  n->feature.u_x_m = mm[0] * 1e-3f;
  n->feature.u_y_m = mm[1] * 1e-3f;
  n->feature.v_x_m = mm[2] * 1e-3f;
  n->feature.v_y_m = mm[3] * 1e-3f;
  if (!r->Get(&n->feature.threshold_m)) return Truncated("node");
  return absl::OkStatus();
}

absl::Status ReadLeaf(Reader* r, int num_parts, ForestLeaf* leaf) {
  leaf->part_probability.resize(static_cast<size_t>(num_parts));
  float sum = 0;
  for (float& p : leaf->part_probability) {
    uint8_t b = 0;
    if (!r->Get(&b)) return Truncated("leaf");
    p = b / 255.0f;
    sum += p;
  }
  for (float& p : leaf->part_probability) p = sum > 0 ? p / sum : 1.0f / num_parts;
  for (JointVote& v : leaf->votes) {
    uint8_t weight = 0;
    int16_t mm[3];
    if (!r->Get(&v.joint) || !r->Get(&weight)) return Truncated("leaf");
    for (int16_t& m : mm) {
      if (!r->Get(&m)) return Truncated("leaf");
    }
    v.weight = weight / 255.0f;
    v.offset_m = Eigen::Vector3f(mm[0], mm[1], mm[2]) * 1e-3f;
  }
  return absl::OkStatus();
}

absl::Status ReadTree(Reader* r, int num_parts, DecisionTree* tree) {
  uint32_t num_nodes = 0, num_leaves = 0;
  if (!r->Get(&num_nodes) || !r->Get(&num_leaves)) return Truncated("tree header");
  const size_t leaf_bytes = static_cast<size_t>(num_parts) + kMaxLeafVotes * kVoteBytes;
  // Both counts are checked against the bytes left before anything is sized.
  if (num_nodes == 0 || num_nodes > r->left() / kNodeBytes ||
      num_leaves > (r->left() - num_nodes * kNodeBytes) / leaf_bytes) {
    return Truncated("tree sizes exceed the file");
  }
  tree->nodes.resize(num_nodes);
  for (ForestNode& n : tree->nodes) {
    if (absl::Status s = ReadNode(r, &n); !s.ok()) return s;
  }
  tree->leaves.resize(num_leaves);
  for (ForestLeaf& leaf : tree->leaves) {
    if (absl::Status s = ReadLeaf(r, num_parts, &leaf); !s.ok()) return s;
  }
  return absl::OkStatus();
}

absl::Status ValidateTree(const DecisionTree& tree, int num_parts, int index) {
  const auto bad = [index](const std::string& what) {
    return absl::InvalidArgumentError(absl::StrCat("tracker forest: tree ", index, ": ", what));
  };
  const int64_t n = static_cast<int64_t>(tree.nodes.size());
  if (n == 0) return bad("no nodes");
  for (int64_t i = 0; i < n; ++i) {
    const ForestNode& node = tree.nodes[static_cast<size_t>(i)];
    if (node.left < 0) {
      if (node.leaf < 0 || node.leaf >= static_cast<int64_t>(tree.leaves.size())) {
        return bad(absl::StrCat("node ", i, " names leaf ", node.leaf));
      }
      continue;
    }
    if (node.left <= i || node.right <= i || node.left >= n || node.right >= n) {
      return bad(absl::StrCat("node ", i, " has children out of order"));
    }
    const SplitFeature& f = node.feature;
    if (!std::isfinite(f.threshold_m) || !std::isfinite(f.u_x_m) || !std::isfinite(f.u_y_m) ||
        !std::isfinite(f.v_x_m) || !std::isfinite(f.v_y_m)) {
      return bad(absl::StrCat("node ", i, " has a non-finite feature"));
    }
  }
  for (const ForestLeaf& leaf : tree.leaves) {
    if (static_cast<int>(leaf.part_probability.size()) != num_parts) return bad("leaf size");
    for (const JointVote& v : leaf.votes) {
      if (v.joint != kNoJoint && v.joint >= body::kNumKinectV2Joints) return bad("vote joint");
      if (!std::isfinite(v.weight) || !v.offset_m.allFinite()) return bad("vote value");
    }
  }
  return absl::OkStatus();
}

}  // namespace

BodyPartForest::BodyPartForest(int num_parts, std::vector<DecisionTree> trees,
                               std::string description)
    : num_parts_(num_parts), trees_(std::move(trees)), description_(std::move(description)) {}

absl::Status BodyPartForest::Validate() const {
  if (num_parts_ < 1 || num_parts_ > static_cast<int>(kMaxParts)) {
    return absl::InvalidArgumentError(absl::StrCat("tracker forest: ", num_parts_, " parts"));
  }
  if (trees_.empty() || trees_.size() > kMaxTrees) {
    return absl::InvalidArgumentError(absl::StrCat("tracker forest: ", trees_.size(), " trees"));
  }
  for (size_t t = 0; t < trees_.size(); ++t) {
    if (absl::Status s = ValidateTree(trees_[t], num_parts_, static_cast<int>(t)); !s.ok()) {
      return s;
    }
  }
  return absl::OkStatus();
}

absl::Status BodyPartForest::Save(const std::string& path) const {
  if (absl::Status s = Validate(); !s.ok()) return s;
  Writer w;
  w.PutBytes(std::string(kMagic, sizeof(kMagic)));
  w.Put(kVersion);
  w.Put(static_cast<uint32_t>(num_parts_));
  w.Put(static_cast<uint32_t>(trees_.size()));
  w.Put(static_cast<uint32_t>(description_.size()));
  w.PutBytes(description_);
  for (const DecisionTree& tree : trees_) WriteTree(tree, num_parts_, &w);
  const std::string tmp = path + ".partial";
  {
    std::ofstream file(tmp, std::ios::binary | std::ios::trunc);
    file.write(w.out().data(), static_cast<std::streamsize>(w.out().size()));
    if (!file.good()) return absl::PermissionDeniedError(absl::StrCat(path, ": cannot write"));
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    return absl::PermissionDeniedError(absl::StrCat(path, ": cannot move the forest in place"));
  }
  return absl::OkStatus();
}

absl::StatusOr<BodyPartForest> BodyPartForest::Parse(const std::string& bytes) {
  Reader r(bytes);
  std::string magic;
  uint32_t version = 0, num_parts = 0, num_trees = 0, description_bytes = 0;
  if (!r.GetBytes(sizeof(kMagic), &magic) || magic != std::string(kMagic, sizeof(kMagic))) {
    return absl::DataLossError("not a tracker forest (.rtf): bad magic");
  }
  if (!r.Get(&version)) return Truncated("header");
  if (version != kVersion) {
    return absl::InvalidArgumentError(
        absl::StrCat("tracker forest version ", version, " (this build reads ", kVersion, ")"));
  }
  if (!r.Get(&num_parts) || !r.Get(&num_trees) || !r.Get(&description_bytes)) {
    return Truncated("header");
  }
  if (num_parts == 0 || num_parts > kMaxParts || num_trees == 0 || num_trees > kMaxTrees) {
    return absl::DataLossError("tracker forest: part or tree count out of range");
  }
  std::string description;
  if (!r.GetBytes(description_bytes, &description)) return Truncated("description");
  std::vector<DecisionTree> trees(num_trees);
  for (DecisionTree& tree : trees) {
    if (absl::Status s = ReadTree(&r, static_cast<int>(num_parts), &tree); !s.ok()) return s;
  }
  if (r.left() != 0) return absl::DataLossError("tracker forest: trailing bytes");
  BodyPartForest forest(static_cast<int>(num_parts), std::move(trees), std::move(description));
  if (absl::Status s = forest.Validate(); !s.ok()) return absl::DataLossError(s.message());
  return forest;
}

absl::StatusOr<BodyPartForest> BodyPartForest::Load(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) return absl::NotFoundError(absl::StrCat(path, ": no tracker forest there"));
  std::stringstream buffer;
  buffer << file.rdbuf();
  absl::StatusOr<BodyPartForest> forest = Parse(buffer.str());
  if (!forest.ok()) {
    return absl::Status(forest.status().code(),
                        absl::StrCat(path, ": ", forest.status().message()));
  }
  return forest;
}

int64_t BodyPartForest::num_nodes() const {
  int64_t n = 0;
  for (const DecisionTree& t : trees_) n += static_cast<int64_t>(t.nodes.size());
  return n;
}

int BodyPartForest::max_depth() const {
  int deepest = 0;
  for (const DecisionTree& t : trees_) {
    std::vector<int> depth(t.nodes.size(), 0);
    for (size_t i = 0; i < t.nodes.size(); ++i) {
      if (t.nodes[i].left < 0) {
        deepest = std::max(deepest, depth[i]);
        continue;
      }
      depth[static_cast<size_t>(t.nodes[i].left)] = depth[i] + 1;
      depth[static_cast<size_t>(t.nodes[i].right)] = depth[i] + 1;
    }
  }
  return deepest;
}

}  // namespace reenact::tracking
