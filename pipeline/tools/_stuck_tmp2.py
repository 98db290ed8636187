import sys, numpy as np, gbmodel
from pipeline.config import compose
from pipeline.plan import plan
lim = sys.argv[1]; E = int(sys.argv[2]); k = int(sys.argv[3])
cfg = compose(["experiment=fig7", "learner.solver=lstsq", f"learner.epochs={E}", "trials.count=20", f"learner.limit={lim}"])
t = [t for t in plan(cfg) if t["growth_label"] == "TG100"][k]
spec = gbmodel.TrialSpec.from_dict(t["spec"])
r = gbmodel.run_trial(spec, np.random.default_rng(np.random.SeedSequence(**t["seed"])))
print(" ".join(f"{e}:{1e3*a:.1f}" for e, a in zip(r.epoch, r.abs_error) if e in (1,5,10,20,50,100,150,200,300,400,500,700,1000,1500,2000)))
