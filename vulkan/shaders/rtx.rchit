#version 460
// rtx.rchit: the closest hit: its t, reference and the hardware's barycentrics into the payload.
// instanceCustomIndex is the scene instance, the primitive index its triangle (vulkan/rtx.cpp).
#extension GL_GOOGLE_include_directive : require
#include "rtx_common.glsl"

layout(location = 0) rayPayloadInEXT RtxPayload payload;
hitAttributeEXT vec2 barycentrics;

void main() {
  payload.t = gl_HitTEXT;
  payload.ref = ref_pack(uint(gl_InstanceCustomIndexEXT), uint(gl_PrimitiveID));
  payload.u = barycentrics.x;
  payload.v = barycentrics.y;
}
