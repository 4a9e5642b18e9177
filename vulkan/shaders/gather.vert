#version 460
// gather.vert: the raster gather (vulkan/frame.h): one draw per instance, three vertices per
// triangle, the world-space vertices of the geometry buffer (as the grid's build wrote them)
// projected by the frame's camera. Reversed depth: z_clip = near plane, w = camera depth, so
// depth = near / z, 1 at the near plane and 0 at infinity (depth test GREATER). Zero-area
// triangles are clipped away.
#extension GL_GOOGLE_include_directive : require
#include "frame_common.glsl"

layout(location = 0) flat out uint out_ref;

void main() {
  const uint instance = uint(gl_InstanceIndex);
  const uint triangle = uint(gl_VertexIndex) / 3u;
  const uint corner = uint(gl_VertexIndex) - 3u * triangle;
  const GridTriangle tri = triangles[instances[instance].tri_offset + triangle];
  const vec3 p = corner == 0u ? tri.v0 : (corner == 1u ? tri.v1 : tri.v2);
  const CameraParams c = fp.camera;
  const vec3 q = p - c.eye;
  const float x = sh_dot(q, c.right), y = sh_dot(q, c.up), z = sh_dot(q, c.forward);
  gl_Position = vec4(x / (c.tan_half_fov * c.aspect), -y / c.tan_half_fov, fp.near_plane, z);
  // Zero-area triangles are never hit (the grid does not insert them, the compute gather skips
  // them), but projected they may cover a pixel centre by rounding: all three corners go outside
  // the clip volume, so the triangle is clipped away.
  if (triangle_zero_area(tri.v0, tri.v1, tri.v2)) gl_Position = vec4(2.0f, 2.0f, 0.0f, 1.0f);
  out_ref = ref_pack(instance, triangle);
}
