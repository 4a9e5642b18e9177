#version 460
// rtx.rmiss: no hit.
#extension GL_GOOGLE_include_directive : require
#include "rtx_common.glsl"

layout(location = 0) rayPayloadInEXT RtxPayload payload;

void main() { payload.ref = kNoRef; }
