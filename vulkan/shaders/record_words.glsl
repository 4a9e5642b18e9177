// record_words.glsl: the ray and hit records (common/shared/records.h) as 16-byte words, so that a
// shader stores a hit in two 16-byte stores and loads or stores a ray in three, where a store of
// the record's members one by one writes 4 bytes at a time (a record's members are scalars and
// vec3s: nothing tells the compiler that the record is 16-byte aligned). A shader that moves
// records declares a uvec4 view of the same binding beside the record's (std430: a RayRecord is
// three words, a HitRecord two, a GatherTexel three) and goes through these.
#ifndef GRIDRT_RECORD_WORDS_GLSL
#define GRIDRT_RECORD_WORDS_GLSL

void hit_to_words(HitRecord h, out uvec4 w0, out uvec4 w1) {
  w0 = uvec4(floatBitsToUint(h.t), h.instance, h.triangle, floatBitsToUint(h.u));
  w1 = uvec4(floatBitsToUint(h.v), h.flags, h.cells, h.tests);
}

void ray_to_words(RayRecord r, out uvec4 w0, out uvec4 w1, out uvec4 w2) {
  w0 = uvec4(floatBitsToUint(r.org), floatBitsToUint(r.tmin));
  w1 = uvec4(floatBitsToUint(r.dir), floatBitsToUint(r.tmax));
  w2 = uvec4(floatBitsToUint(r.launch_normal), r.launch_ref);
}

RayRecord ray_from_words(uvec4 w0, uvec4 w1, uvec4 w2) {
  return RayRecord(uintBitsToFloat(w0.xyz), uintBitsToFloat(w0.w), uintBitsToFloat(w1.xyz), uintBitsToFloat(w1.w),
                   uintBitsToFloat(w2.xyz), w2.w);
}

void gather_to_words(GatherTexel g, out uvec4 w0, out uvec4 w1, out uvec4 w2) {
  w0 = uvec4(floatBitsToUint(g.position), g.material);
  w1 = uvec4(floatBitsToUint(g.normal), g.launch_ref);
  w2 = uvec4(floatBitsToUint(g.uv), floatBitsToUint(g.t), g.pad0);
}

GatherTexel gather_from_words(uvec4 w0, uvec4 w1, uvec4 w2) {
  return GatherTexel(uintBitsToFloat(w0.xyz), w0.w, uintBitsToFloat(w1.xyz), w1.w, uintBitsToFloat(w2.xy),
                     uintBitsToFloat(w2.z), w2.w);
}

#endif
