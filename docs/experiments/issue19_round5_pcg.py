#!/usr/bin/python3
# Issue 19, fifth round: conjugate gradients on the engine's own Newton systems, offline.
# The systems come from a build with docs/experiments/issue19_round5_dump.patch applied:
#   NEXDYN_DUMP=/tmp/dump NEXDYN_DUMP_MIN=3000 NEXDYN_DUMP_EVERY=100 ./build/nexdyn run ...
# Then (Debian: apt-get install python3-scipy):
#   /usr/bin/python3 docs/experiments/issue19_round5_pcg.py /tmp/dump/model.bin body,mesh,jacobi3 /tmp/dump/sys_*.bin
# Preconditioners: an exact (SuperLU) factor of the matrix restricted to each body's block
# ("body"), to the vertex pairs that share a tet ("mesh"), or to the 3x3 vertex blocks
# ("jacobi3"). Prints CG iterations to relative residuals of 1e-2 .. 1e-6 and the error of the
# direction against the exact solve (max norm).
import os
import sys
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

def load_model(path):
    with open(path, 'rb') as f:
        nv, nt = np.fromfile(f, np.int64, 2)
        body = np.fromfile(f, np.int32, nv)
        tets = np.fromfile(f, np.int32, 4 * nt).reshape(nt, 4)
    return body, tets

def load_sys(path):
    with open(path, 'rb') as f:
        n, nnz, nv = np.fromfile(f, np.int64, 3)
        cp = np.fromfile(f, np.int64, n + 1)
        ri = np.fromfile(f, np.int64, nnz)
        val = np.fromfile(f, np.float64, nnz)
        rhs = np.fromfile(f, np.float64, n)
        verts = np.fromfile(f, np.int32, nv)
    U = sp.csc_matrix((val, ri, cp), shape=(n, n))
    A = U + sp.triu(U, 1).T
    return A.tocsr(), rhs, verts

def mesh_pairs(tets, nvert):
    rows, cols = [], []
    for a in range(4):
        for b in range(4):
            rows.append(tets[:, a]); cols.append(tets[:, b])
    r = np.concatenate(rows); c = np.concatenate(cols)
    M = sp.csr_matrix((np.ones(len(r), np.int8), (r, c)), shape=(nvert, nvert))
    M.sum_duplicates()
    return M

def pcg(A, b, Msolve, tols, maxit=3000):
    x = np.zeros_like(b); r = b.copy(); z = Msolve(r); p = z.copy(); rz = r @ z
    bn = np.linalg.norm(b); out = {}; ti = 0
    hist = []
    for k in range(1, maxit + 1):
        Ap = A @ p; a = rz / (p @ Ap); x += a * p; r -= a * Ap
        rel = np.linalg.norm(r) / bn
        while ti < len(tols) and rel <= tols[ti]:
            out[tols[ti]] = (k, x.copy()); ti += 1
        if ti == len(tols): break
        z = Msolve(r); rzn = r @ z; p = z + (rzn / rz) * p; rz = rzn
    for t in tols[ti:]: out[t] = (None, x.copy())
    return out

def main(model_path, sys_paths, kinds):
    body, tets = load_model(model_path)
    nvert = len(body)
    mesh = mesh_pairs(tets, nvert)
    for path in sys_paths:
        A, b, verts = load_sys(path)
        n = A.shape[0]
        dof_v = np.repeat(verts, 3)
        Acoo = A.tocoo()
        vi, vj = dof_v[Acoo.row], dof_v[Acoo.col]
        t0 = time.time()
        lu = sla.splu(A.tocsc(), permc_spec='MMD_AT_PLUS_A', options=dict(SymmetricMode=True))
        tf = time.time() - t0
        xs = lu.solve(b)
        nb = len(np.unique(body[verts]))
        print(f'{os.path.basename(path)}: n {n}, bodies {nb}, nnz {A.nnz}, exact factor nnz(L+U) {lu.L.nnz + lu.U.nnz} ({tf:.1f}s)')
        for kind in kinds:
            if kind == 'body':
                keep = body[vi] == body[vj]
            elif kind == 'mesh':
                keep = (vi == vj) | (np.asarray(mesh[vi, vj]).ravel() > 0)
            elif kind == 'jacobi3':
                keep = vi == vj
            P = sp.csc_matrix((Acoo.data[keep], (Acoo.row[keep], Acoo.col[keep])), shape=(n, n))
            try:
                plu = sla.splu(P, permc_spec='MMD_AT_PLUS_A', options=dict(SymmetricMode=True))
            except RuntimeError as e:
                print(f'  {kind}: factor failed {e}'); continue
            dropped = A.nnz - P.nnz
            tols = [1e-2, 1e-3, 1e-4, 1e-6]
            out = pcg(A, b, plu.solve, tols)
            s = ', '.join(
                f'{t:g}: {k} its, dir err {np.abs(x - xs).max() / np.abs(xs).max():.1e}' for t, (k, x) in out.items())
            print(f'  {kind}: dropped {dropped} of {A.nnz}, P factor nnz {plu.L.nnz + plu.U.nnz}; {s}')
        sys.stdout.flush()

if __name__ == '__main__':
    kinds = sys.argv[2].split(',')
    main(sys.argv[1], sys.argv[3:], kinds)
