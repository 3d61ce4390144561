// Sampling an image stored as the layers of a 2D array texture (see terrain/ReferenceMesh.h TileLayout): tiles
// overlap by uTileBorder texels so bilinear filtering is seamless; gradients come from the continuous image
// coordinate so mip selection does not jump at tile edges.
uniform vec2 uImageSize;  // image pixels
uniform vec2 uTileSize;   // texels per layer, borders included
uniform float uTileStep;  // image pixels between tile origins
uniform float uTileBorder;
uniform int uTilesX;
uniform int uTilesY;

vec4 sampleTiledImage(sampler2DArray image, vec2 uv) {
    vec2 p = uv * uImageSize;
    vec2 tile = clamp(floor(p / uTileStep), vec2(0.0), vec2(uTilesX - 1, uTilesY - 1));
    vec2 local = (p - tile * uTileStep + uTileBorder) / uTileSize;
    vec2 gx = dFdx(p) / uTileSize, gy = dFdy(p) / uTileSize;
    return textureGrad(image, vec3(local, tile.y * float(uTilesX) + tile.x), gx, gy);
}
