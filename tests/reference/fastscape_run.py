"""fastscapelib 0.3.0's landscape evolution on a raster grid, for tests/landscape.rs and
`terrafuse bench landscape`. Arguments: IN OUT ROWS COLS DY DX U K M N KD DT STEPS.
IN holds ROWS×COLS little-endian f64 heights (row 0 first); OUT gets the heights after STEPS steps
(same layout) followed by the last routing's receivers as f64 flat indices. The step is the one
fastscapelib's examples use: uplift (not on the fixed borders), routing (single flow, MST sink
resolver), SPLEroder, DiffusionADIEroder. Prints {"seconds", "cell_steps_per_s"} (the loop only).
"""
import json
import sys
import time

import numpy as np
import fastscapelib as fs

src, out = sys.argv[1], sys.argv[2]
rows, cols = int(sys.argv[3]), int(sys.argv[4])
dy, dx, u, k, m, n, kd, dt = map(float, sys.argv[5:13])
steps = int(sys.argv[13])

h = np.fromfile(src, dtype="<f8").reshape(rows, cols)
grid = fs.RasterGrid([rows, cols], [dy, dx], fs.NodeStatus.FIXED_VALUE)
flow_graph = fs.FlowGraph(grid, [fs.SingleFlowRouter(), fs.MSTSinkResolver()])
spl = fs.SPLEroder(flow_graph, k, m, n, 1e-5)
diffusion = fs.DiffusionADIEroder(grid, kd)
uplift = np.full_like(h, u)
uplift[[0, -1], :] = 0.0
uplift[:, [0, -1]] = 0.0

start = time.perf_counter()
for _ in range(steps):
    uplifted = h + dt * uplift
    flow_graph.update_routes(uplifted)
    area = flow_graph.accumulate(1.0)
    incised = spl.erode(uplifted, area, dt)
    diffused = diffusion.erode(uplifted - incised, dt)
    h = uplifted - incised - diffused
seconds = time.perf_counter() - start

receivers = flow_graph.impl().receivers[:, 0].astype("<f8")
np.concatenate([h.astype("<f8").ravel(), receivers]).tofile(out)
print(json.dumps({"seconds": seconds, "cell_steps_per_s": rows * cols * steps / seconds}))
