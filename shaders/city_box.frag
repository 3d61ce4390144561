// Occlusion-query boxes: only the depth test matters (colour writes are masked off).
out vec4 fragColor;

void main() { fragColor = vec4(1.0); }
