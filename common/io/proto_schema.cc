#include "common/io/proto_schema.h"

#include <set>

#include <google/protobuf/descriptor.pb.h>

namespace reenact {
namespace {

void AddFileAndDependencies(const google::protobuf::FileDescriptor& file,
                            std::set<std::string>* added,
                            google::protobuf::FileDescriptorSet* set) {
  if (!added->insert(file.name()).second) return;
  for (int i = 0; i < file.dependency_count(); ++i) {
    AddFileAndDependencies(*file.dependency(i), added, set);
  }
  file.CopyTo(set->add_file());
}

}  // namespace

std::string BuildFileDescriptorSet(const google::protobuf::Descriptor& descriptor) {
  google::protobuf::FileDescriptorSet set;
  std::set<std::string> added;
  AddFileAndDependencies(*descriptor.file(), &added, &set);
  return set.SerializeAsString();
}

}  // namespace reenact
