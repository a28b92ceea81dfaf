// Self-describing protobuf schemas for MCAP: the "protobuf" schema encoding
// stores a serialized google.protobuf.FileDescriptorSet holding the message's
// .proto file and every file it depends on, so any reader can decode the
// messages without our .proto files.
#pragma once

#include <string>

#include <google/protobuf/descriptor.h>

namespace reenact {

// Serialized FileDescriptorSet of `descriptor`'s file and all its transitive
// dependencies, dependencies before the files that import them.
std::string BuildFileDescriptorSet(const google::protobuf::Descriptor& descriptor);

}  // namespace reenact
