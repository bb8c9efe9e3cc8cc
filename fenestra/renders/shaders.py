"""GLSL 330 core sources of the raster backend's programs (:class:`renders.gl.GLContext` compiles
them by name): ``mesh`` (textured, daylit material groups with the shadow-map test), ``code`` (the occluder pass's flat element-code colours), ``sky``
(per-pixel sky gradient on a full-screen triangle) and ``fxaa`` (the FXAA post filter, sharing the
sky's full-screen vertex shader).
"""
MESH_VS = """#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec2 texcoord;
layout(location = 2) in vec4 colour;
uniform mat4 PV;
uniform mat4 sun_from_world;
out vec3 spos;
out vec2 uv;
out vec4 col;
void main() {
    gl_Position = PV * vec4(position, 1.0);
    spos = (sun_from_world * vec4(position, 1.0)).xyz;  // affine: interpolates exactly
    uv = texcoord;
    col = colour;
}
"""
# col.rgb: baked light multiplier; col.a: quantised shadow ratio (>= 1: never shaded)
MESH_FS = """#version 330 core
in vec3 spos;
in vec2 uv;
in vec4 col;
uniform sampler2D tex;
uniform int textured;
uniform vec3 base;
uniform sampler2D shadow_map;
uniform int shadows;
uniform float radius;
uniform float far;
uniform int size;
uniform float bias;
uniform vec3 tint;
layout(location = 0) out vec4 frag;
void main() {
    vec3 c = base * col.rgb;
    if (textured != 0) c *= texture(tex, uv).rgb;
    if (shadows != 0 && col.a < 1.0) {
        vec3 s = spos;
        ivec2 ij = ivec2(floor(vec2((s.x / radius + 1.0) * 0.5 * float(size) - 0.5,
                                    (1.0 - s.y / radius) * 0.5 * float(size) - 0.5) + 0.5));
        if (all(greaterThanEqual(ij, ivec2(0))) && all(lessThan(ij, ivec2(size)))) {
            float d = texelFetch(shadow_map, ij, 0).r * far;
            if (d > 0.0 && -s.z > d + bias) c *= col.a * tint;
        }
    }
    frag = vec4(clamp(c, 0.0, 1.0), 1.0);
}
"""
CODE_VS = """#version 330 core
layout(location = 0) in vec3 position;
layout(location = 2) in vec4 colour;
uniform mat4 PV;
flat out vec4 col;
void main() { gl_Position = PV * vec4(position, 1.0); col = colour; }
"""
CODE_FS = """#version 330 core
flat in vec4 col;
out vec4 frag;
void main() { frag = col; }
"""
# full-screen sky: world direction of pixel (u, v) = Minv (u, v, 1); u, v OpenCV pixel coordinates
SKY_VS = """#version 330 core
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2)) * 2.0 - 1.0;
    gl_Position = vec4(p, 1.0, 1.0);
}
"""
SKY_FS = """#version 330 core
uniform mat3 Minv;
uniform float height;
uniform vec3 horizon;
uniform vec3 zenith;
out vec4 frag;
void main() {
    vec3 d = normalize(Minv * vec3(gl_FragCoord.x - 0.5, height - 0.5 - gl_FragCoord.y, 1.0));
    float w = pow(clamp(d.z, 0.0, 1.0), 0.6);
    frag = vec4(clamp((1.0 - w) * horizon + w * zenith, 0.0, 1.0), 1.0);
}
"""


# FXAA (Lottes' FXAA 3 "console" variant): where the local luma contrast exceeds FXAA's edge
# threshold, average 2 or 4 taps along the edge direction; elsewhere the pixel is left as rendered
FXAA_FS = """#version 330 core
uniform sampler2D img;
out vec4 frag;
void main() {
    ivec2 size = textureSize(img, 0);
    vec2 inv = 1.0 / vec2(size);
    vec2 p = gl_FragCoord.xy * inv;
    ivec2 ij = ivec2(gl_FragCoord.xy), lo = max(ij - 1, ivec2(0)), hi = min(ij + 1, size - 1);
    vec3 nw = texelFetch(img, ivec2(lo.x, lo.y), 0).rgb;  // the four diagonal neighbours, clamped
    vec3 ne = texelFetch(img, ivec2(hi.x, lo.y), 0).rgb;
    vec3 sw = texelFetch(img, ivec2(lo.x, hi.y), 0).rgb;
    vec3 se = texelFetch(img, ivec2(hi.x, hi.y), 0).rgb;
    vec3 m = texelFetch(img, ij, 0).rgb;
    vec3 w = vec3(0.299, 0.587, 0.114);
    float lnw = dot(nw, w), lne = dot(ne, w), lsw = dot(sw, w), lse = dot(se, w), lm = dot(m, w);
    float lmin = min(lm, min(min(lnw, lne), min(lsw, lse)));
    float lmax = max(lm, max(max(lnw, lne), max(lsw, lse)));
    if (lmax - lmin < max(1.0 / 32.0, lmax / 8.0)) { frag = vec4(m, 1.0); return; }  // no edge here
    vec2 dir = vec2(-((lnw + lne) - (lsw + lse)), (lnw + lsw) - (lne + lse));
    float reduce = max((lnw + lne + lsw + lse) * (0.25 / 8.0), 1.0 / 128.0);
    float rcp = 1.0 / (min(abs(dir.x), abs(dir.y)) + reduce);
    dir = clamp(dir * rcp, vec2(-8.0), vec2(8.0)) * inv;
    vec3 a = 0.5 * (texture(img, p + dir * (1.0 / 3.0 - 0.5)).rgb + texture(img, p + dir * (2.0 / 3.0 - 0.5)).rgb);
    vec3 b = a * 0.5 + 0.25 * (texture(img, p - dir * 0.5).rgb + texture(img, p + dir * 0.5).rgb);
    float lb = dot(b, w);
    frag = vec4((lb < lmin || lb > lmax) ? a : b, 1.0);
}
"""
