// Occlusion-query boxes (city/CityRendererGL.h): a node's bounding box from the unit cube's corners. Drawn with
// colour and depth writes off inside an occlusion query (Coherent Hierarchical Culling, Wimmer & Bittner 2005).
layout(location = 0) in vec3 aCorner; // 0 or 1 per axis

uniform mat4 uViewProj;
uniform vec3 uBoxMin, uBoxMax;

void main() { gl_Position = uViewProj * vec4(mix(uBoxMin, uBoxMax, aCorner), 1.0); }
