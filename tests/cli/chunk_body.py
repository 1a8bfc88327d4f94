#!/usr/bin/env python3
"""chunk_body.py FILE...: prints, per chunk file, a SHA-256 of what it says
about the voxels or colours: the header from the kind on (grid, cell,
transform, bounds, counts) and every section but PROV (provenance, which
names the input and the arguments). Two runs over equivalent inputs give
equal lines. Layout: schemas/chunk-format.md."""
import hashlib, struct, sys

for path in sys.argv[1:]:
    b = open(path, 'rb').read()
    hsize, = struct.unpack_from('<I', b, 12)
    n, = struct.unpack_from('<I', b, 28)
    nsec, = struct.unpack_from('<I', b, 100)
    h = hashlib.sha256(b[16:104 + 8 * n])
    off = hsize
    for _ in range(nsec):
        tag = b[off:off + 4]
        stored, = struct.unpack_from('<Q', b, off + 16)
        if tag != b'PROV':
            h.update(b[off:off + 32 + stored])
        off += 32 + stored
    print(path.rsplit('/', 1)[-1], h.hexdigest())
