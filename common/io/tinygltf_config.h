// The one way Reenact includes tinygltf (Debian libtinygltf-dev, header-only
// here): images stay the encoded bytes they are (JPEG from the reenactment),
// so stb_image is left out, and JSON comes from Debian's nlohmann-json.
// common/io/gltf_export.cc compiles the implementation
// (TINYGLTF_IMPLEMENTATION) into reenact_io, the only place that does;
// include this header, never <tiny_gltf.h> directly, so that every
// translation unit sees the same TinyGLTF class. Loading a model through it
// needs an image loader (TinyGLTF::SetImageLoader), e.g. KeepEncodedImage.
#pragma once

#ifndef TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE
#endif
#ifndef TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#endif
#ifndef TINYGLTF_NO_EXTERNAL_IMAGE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#endif

#include <tiny_gltf.h>

namespace reenact {

// A tinygltf image loader that keeps the encoded bytes (image.image, with
// as_is set) instead of decoding them.
bool KeepEncodedImage(tinygltf::Image* image, int image_index, std::string* err, std::string* warn,
                      int req_width, int req_height, const unsigned char* bytes, int size,
                      void* user_data);

}  // namespace reenact
