// The deferred terrain resolve (terrain_resolve.frag): one triangle covering the frame.
void main() {
    vec2 corner = vec2(float((gl_VertexID & 1) << 2), float((gl_VertexID & 2) << 1)) - 1.0; // (-1,-1) (3,-1) (-1,3)
    gl_Position = vec4(corner, 0.0, 1.0);
}
