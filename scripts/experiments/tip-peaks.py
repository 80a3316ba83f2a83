#!/usr/bin/env python3
"""How sharp is a tip model's heatmap? For the first N frames of a phyllo-gen set, the tip map's
largest value within ±2 output pixels of each tip a person would click (phyllo_train.tip_truth),
as quantiles and the shares at or above two thresholds. Whole frames, padded to a multiple of 32,
one ONNX Runtime thread.

    models/.venv/bin/python scripts/experiments/tip-peaks.py MODEL.onnx DATASET [FRAMES]
"""

import sys
from pathlib import Path

import numpy as np
import onnxruntime as ort
from PIL import Image
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / 'models'))
from phyllo_train.dataset import read_manifest
from phyllo_train.tip_truth import person_tips
from phyllo_train.contract import load_contract
c=load_contract()
so=ort.SessionOptions(); so.intra_op_num_threads=1
s=ort.InferenceSession(sys.argv[1], so)
data=sys.argv[2]
rows=read_manifest(data)[:int(sys.argv[3]) if len(sys.argv) > 3 else 20]
vals=[]; maxes=[]
for r in rows:
    im=np.asarray(Image.open(f"{data}/{r['image']}").convert('RGB'),np.float32)/255
    x=(im-np.array(c.mean))/np.array(c.std); h,w=x.shape[:2]
    x=np.pad(x,((0,(-h)%32),(0,(-w)%32),(0,0))).transpose(2,0,1)[None].astype(np.float32)
    out=dict(zip([o.name for o in s.get_outputs()], s.run(None,{'image':x})))
    tip=out['tip'][0,0]
    for k,(tx,ty) in person_tips(r).items():
        yy,xx=int(ty/2),int(tx/2)
        vals.append(tip[max(0,yy-2):yy+3,max(0,xx-2):xx+3].max())
    maxes.append(tip.max())
v=np.array(vals); print('true tips', len(v), 'peak near tip: quantiles 10/25/50/75/90', np.round(np.quantile(v,[.1,.25,.5,.75,.9]),3), 'share >=0.3', (v>=0.3).mean(), '>=0.15', (v>=0.15).mean())
