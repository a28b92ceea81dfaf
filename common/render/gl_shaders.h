// GLSL sources of OffscreenRenderer (internal to reenact_render).
#pragma once

namespace reenact::render::internal {

// Vertex stage: attribute locations 0 position (model frame, metres),
// 1 normal, 2 uv, 3 colour (sRGB). Passes depth along the optical axis, world
// position and normal, uv and linear colour.
inline constexpr char kMeshVertexShader[] = R"glsl(
#version 330 core
layout(location = 0) in vec3 in_position_m;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;
layout(location = 3) in vec3 in_colour_srgb;
uniform mat4 u_clip_from_model;
uniform mat4 u_world_from_model;
uniform vec4 u_camera_z_from_model;  // Row 2 of camera_from_model.
out vec3 v_position_world;
out vec3 v_normal_world;
out vec2 v_uv;
out vec3 v_colour_linear;
out float v_depth_m;

vec3 SrgbToLinear(vec3 c) {
  return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), c));
}

void main() {
  vec4 position = vec4(in_position_m, 1.0);
  gl_Position = u_clip_from_model * position;
  v_depth_m = dot(u_camera_z_from_model, position);
  v_position_world = (u_world_from_model * position).xyz;
  v_normal_world = mat3(u_world_from_model) * in_normal;
  v_uv = in_uv;
  v_colour_linear = SrgbToLinear(in_colour_srgb);
}
)glsl";

// Fragment stage: outputs 0 colour (linear; the sRGB attachment encodes it),
// 1 depth along the optical axis (metres), 2 label, 3 world normal.
// u_mode: 0 flat colour, 1 vertex colour, 2 texture.
inline constexpr char kMeshFragmentShader[] = R"glsl(
#version 330 core
in vec3 v_position_world;
in vec3 v_normal_world;
in vec2 v_uv;
in vec3 v_colour_linear;
in float v_depth_m;
uniform int u_mode;
uniform bool u_lit;
uniform bool u_has_normals;
uniform bool u_headlight;
uniform vec3 u_colour_linear;
uniform sampler2D u_texture;
uniform vec3 u_camera_centre_world;
uniform vec3 u_direction_to_light_world;
uniform float u_ambient;
uniform float u_diffuse;
uniform uint u_label;
layout(location = 0) out vec4 out_colour;
layout(location = 1) out float out_depth_m;
layout(location = 2) out uint out_label;
layout(location = 3) out vec4 out_normal_world;

void main() {
  vec3 to_camera = normalize(u_camera_centre_world - v_position_world);
  vec3 normal;
  if (u_has_normals) {
    normal = normalize(v_normal_world);
  } else {
    // Face normal, turned to the outside: toward the camera on front faces.
    normal = normalize(cross(dFdx(v_position_world), dFdy(v_position_world)));
    if (dot(normal, to_camera) < 0.0) normal = -normal;
    if (!gl_FrontFacing) normal = -normal;
  }
  vec3 albedo = u_colour_linear;
  if (u_mode == 1) albedo = v_colour_linear;
  // Textures are stored top row first, so t = 1 - v.
  if (u_mode == 2) {
    vec4 texel = texture(u_texture, vec2(v_uv.x, 1.0 - v_uv.y));
    if (texel.a < 0.5) discard;  // Alpha-tested textures (RGB ones have alpha 1).
    albedo = texel.rgb;
  }
  float shade = 1.0;
  if (u_lit) {
    vec3 light = u_headlight ? to_camera : u_direction_to_light_world;
    vec3 lit_normal = dot(normal, to_camera) < 0.0 ? -normal : normal;  // Two-sided.
    shade = u_ambient + u_diffuse * max(dot(lit_normal, light), 0.0);
  }
  out_colour = vec4(albedo * shade, 1.0);
  out_depth_m = v_depth_m;
  out_label = u_label;
  out_normal_world = vec4(normal, 0.0);
}
)glsl";

}  // namespace reenact::render::internal
