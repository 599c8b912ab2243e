"""A casadi Function called on numpy arrays through its ``FunctionBuffer`` (no DM conversion of the inputs
or outputs): the single-level fits call their KKT functions thousands of times per fit."""

from __future__ import annotations

import numpy as np


class BufferedCall:
    """``f`` called through its ``FunctionBuffer``; a sparse output comes back as a scipy CSC matrix of the
    output's sparsity (built once, its values replaced at each call: use it before the next call)."""

    def __init__(self, f):
        from scipy.sparse import csc_matrix

        self.buffer, self.run = f.buffer()
        self.args = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
        self.res = [np.zeros(f.nnz_out(i)) for i in range(f.n_out())]
        self.out = []
        for i in range(f.n_out()):
            sp = f.sparsity_out(i)
            colind, row = sp.get_ccs()
            self.out.append(None if sp.is_dense() else csc_matrix((self.res[i], row, colind), shape=sp.shape))
        self.shapes = [f.sparsity_out(i).shape for i in range(f.n_out())]
        for i, a in enumerate(self.args):
            self.buffer.set_arg(i, memoryview(a))
        for i, r in enumerate(self.res):
            self.buffer.set_res(i, memoryview(r))

    def __call__(self, *args):
        for a, x in zip(self.args, args):
            a[:] = np.ravel(x)
        self.run()
        out = []
        for r, m, (n1, n2) in zip(self.res, self.out, self.shapes):
            if m is None:
                out.append(r.reshape(n2, n1).T.copy() if n2 > 1 else r.copy())
            else:
                m.data = r.copy()
                out.append(m)
        return out
