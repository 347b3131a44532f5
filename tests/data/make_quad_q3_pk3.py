#!/usr/bin/env python3
"""Writes quad_q3.pk3: a minimal Quake 3 BSP (IBSP v46) of one 64x32-unit quad face (z = 8,
texture UVs 0..2 x 0..1, i.e. tiling twice along u), zipped as maps/quad.bsp, for
tests/test_mesh_import.cpp. Made here, no game data. Usage: make_quad_q3_pk3.py OUT.pk3"""
import struct, sys, zipfile

def lump_bytes():
    textures = struct.pack('<64sii', b'textures/test/brick', 0, 1)
    # vertex: pos[3], texcoord uv[2], lightmap uv[2], normal[3], rgba
    corners = [((0, 0, 8), (0, 0)), ((64, 0, 8), (2, 0)), ((64, 32, 8), (2, 1)), ((0, 32, 8), (0, 1))]
    vertexes = b''.join(struct.pack('<3f2f2f3f4B', *p, *uv, 0.0, 0.0, 0.0, 0.0, 1.0, 255, 255, 255, 255)
                        for p, uv in corners)
    # Quake 3 winds front faces clockwise (seen from +z here: 0, 2, 1 and 0, 3, 2).
    meshverts = struct.pack('<6i', 0, 2, 1, 0, 3, 2)
    face = struct.pack('<7i', 0, -1, 1, 0, 4, 0, 6) + struct.pack('<i2i2i', 0, 0, 0, 8, 8) + \
        struct.pack('<3f6f3f2i', 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0)
    lightmaps = bytes(128 * 128 * 3)
    lumps = [b'{\n"classname" "worldspawn"\n}\n\0', textures] + [b''] * 8 + [vertexes, meshverts, b'', face, lightmaps, b'', b'']
    return lumps

lumps = lump_bytes()
offset = 8 + 17 * 8
header, body = b'IBSP' + struct.pack('<i', 46), b''
for l in lumps:
    header += struct.pack('<ii', offset + len(body), len(l))
    body += l + bytes((-len(l)) % 4)
with zipfile.ZipFile(sys.argv[1], 'w', zipfile.ZIP_DEFLATED) as z:
    z.writestr('maps/quad.bsp', header + body)
