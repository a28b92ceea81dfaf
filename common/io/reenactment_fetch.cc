#include "common/io/reenactment_fetch.h"

#include <utility>

#include "absl/strings/str_cat.h"

namespace reenact {

absl::Status AppendFetchChunk(v1::FetchReenactmentChunk& chunk, ReenactmentData* data, int* stage) {
  const int kind = static_cast<int>(chunk.chunk_case());
  if (kind == 0) return absl::DataLossError("the server sent an empty Fetch message");
  // Rank of each kind in the promised order (the body mesh's field number is
  // the newest, but it comes second).
  const auto rank = [](int k) {
    if (k == v1::FetchReenactmentChunk::kBodyMesh) return 3;
    if (k == v1::FetchReenactmentChunk::kAppearanceMp4Piece) return 3;
    return 2 * k;
  };
  const int info_rank = rank(v1::FetchReenactmentChunk::kInfo);
  if (rank(kind) < *stage || (rank(kind) != info_rank && *stage == 0) ||
      (rank(kind) == info_rank && *stage != 0)) {
    return absl::DataLossError(
        absl::StrCat("the server sent Fetch message kind ", kind, " out of order"));
  }
  *stage = rank(kind);
  switch (chunk.chunk_case()) {
    case v1::FetchReenactmentChunk::kInfo:
      data->info = std::move(*chunk.mutable_info());
      break;
    case v1::FetchReenactmentChunk::kBodyMesh:
      data->body.push_back(std::move(*chunk.mutable_body_mesh()));
      break;
    case v1::FetchReenactmentChunk::kAppearanceMp4Piece:
      if (data->body.empty()) {
        return absl::DataLossError("the server sent a piece of an appearance video with no body");
      }
      data->body.back().mutable_appearance()->mutable_mp4()->append(chunk.appearance_mp4_piece());
      break;
    case v1::FetchReenactmentChunk::kPartMesh:
      data->parts.push_back(std::move(*chunk.mutable_part_mesh()));
      break;
    case v1::FetchReenactmentChunk::kFrames:
      for (v1::PartFrame& frame : *chunk.mutable_frames()->mutable_frames()) {
        data->frames.push_back(std::move(frame));
      }
      break;
    case v1::FetchReenactmentChunk::kKeyframe:
      data->keyframes.push_back(std::move(*chunk.mutable_keyframe()));
      break;
    default:
      break;
  }
  return absl::OkStatus();
}

}  // namespace reenact
