"""The numbers of the report's tables that the pages quote (README.md, docs/, findings.md),
named here, each a literal (pipeline/studies/values.py; the sections name them with ctx.quote):
name -> the row's keys in its table, its column and scale."""

# the iCub's final error (fig7_20trials), its range over the conditions, named wherever measured
RANGED = {  # column -> the names of its (min, max) over the conditions
    "final_abs_error_mean": ("summary.fig7_20trials.final_abs_error_mean_mm.min",
                             "summary.fig7_20trials.final_abs_error_mean_mm.max"),
    "final_path_abs_error_mean": ("summary.fig7_20trials.final_path_abs_error_mean_mm.min",
                                  "summary.fig7_20trials.final_path_abs_error_mean_mm.max"),
    "final_uniform_abs_error_mean": ("summary.fig7_20trials.final_uniform_abs_error_mean_mm.min",
                                     "summary.fig7_20trials.final_uniform_abs_error_mean_mm.max")}

# summary.csv: figure, condition, column, scale
SUMMARY = {
    'summary.fig5.tg1000.final_abs_error_mean_mm': ('fig5', 'TG1000', 'final_abs_error_mean', 1e3),
    'summary.fig4.const1.0.final_abs_error_mean_mm':
        ('fig4', 'const1.0', 'final_abs_error_mean', 1e3),
    'summary.fig7_20trials.const0.5.final_abs_error_mean_mm':
        ('fig7_20trials', 'const0.5', 'final_abs_error_mean', 1e3),
    'summary.fig7_20trials.const1.0.final_abs_error_mean_mm':
        ('fig7_20trials', 'const1.0', 'final_abs_error_mean', 1e3),
    'summary.fig4.const0.5.final_abs_error_mean_mm':
        ('fig4', 'const0.5', 'final_abs_error_mean', 1e3),
    'summary.fig5.const0.5.final_abs_error_mean_mm':
        ('fig5', 'const0.5', 'final_abs_error_mean', 1e3),
    'summary.fig2.const1.0.final_abs_error_mean_mm':
        ('fig2', 'const1.0', 'final_abs_error_mean', 1e3),
}
# the row of the final error, the row it is divided by, its column
SUMMARY_RATIOS = {
    'summary.fig4.const0.5.final_abs_error_mean.over.const1.0':
        (('fig4', 'const0.5'), ('fig4', 'const1.0'), 'final_abs_error_mean'),
    'summary.fig4.const0.5.final_abs_error_mean.over.paper_final_abs_error':
        (('fig4', 'const0.5'), ('fig4', 'const0.5'), 'paper_final_abs_error'),
    'summary.fig5.const0.5.final_abs_error_mean.over.paper_final_abs_error':
        (('fig5', 'const0.5'), ('fig5', 'const0.5'), 'paper_final_abs_error'),
}
# scorecard.csv: figure, claim, where, column, scale
SCORECARD = {
    'scorecard.fig4.rise_none.tg10000.value_pct': ('fig4', 'rise_none', 'TG10000', 'value', 100),
    'scorecard.fig4.rise_none.tg10000.high_pct': ('fig4', 'rise_none', 'TG10000', 'high', 100),
    'scorecard.fig5.rise_none.tg10000.value_pct': ('fig5', 'rise_none', 'TG10000', 'value', 100),
    'scorecard.fig5.rise_none.tg10000.high_pct': ('fig5', 'rise_none', 'TG10000', 'high', 100),
    'scorecard.fig4.rise.tg1000.value_pct': ('fig4', 'rise', 'TG1000', 'value', 100),
    'scorecard.fig2.stages.value_mm':
        ('fig2', 'stages', 'final error at the worse extreme', 'value', 1e3),
    'scorecard.fig4.above_start.tg1000.value_pct': ('fig4', 'above_start', 'TG1000', 'value', 100),
    'scorecard.fig5.above_start.tg1000.value_pct': ('fig5', 'above_start', 'TG1000', 'value', 100),
    'scorecard.fig5.rise.tg1000.value_pct': ('fig5', 'rise', 'TG1000', 'value', 100),
    'scorecard.fig4.above_start.tg100.value_pct': ('fig4', 'above_start', 'TG100', 'value', 100),
    'scorecard.fig5.above_start.tg100.value_pct': ('fig5', 'above_start', 'TG100', 'value', 100),
    'scorecard.fig4.rise.tg100.value_pct': ('fig4', 'rise', 'TG100', 'value', 100),
    'scorecard.fig5.rise.tg100.value_pct': ('fig5', 'rise', 'TG100', 'value', 100),
    'scorecard.fig4.rise.tg10.value_pct': ('fig4', 'rise', 'TG10', 'value', 100),
    'scorecard.fig5.rise.tg10.value_pct': ('fig5', 'rise', 'TG10', 'value', 100),
    'scorecard.fig4.rise.tg1000.low_pct': ('fig4', 'rise', 'TG1000', 'low', 100),
    'scorecard.fig4.rise.tg1000.high_pct': ('fig4', 'rise', 'TG1000', 'high', 100),
    'scorecard.fig7_20trials.rise.tg10.value_pct': ('fig7_20trials', 'rise', 'TG10', 'value', 100),
    'scorecard.fig7_20trials.rise.tg100.value_pct':
        ('fig7_20trials', 'rise', 'TG100', 'value', 100),
    'scorecard.fig7_20trials.rise.tg1000.value_pct':
        ('fig7_20trials', 'rise', 'TG1000', 'value', 100),
    'scorecard.fig7_20trials.final.const0.5.value': ('fig7_20trials', 'final', 'const0.5', 'value'),
    'scorecard.fig7_20trials.after.tg10_rebound.value_pct':
        ('fig7_20trials', 'after', 'TG10 rebound', 'value', 100),
    'scorecard.fig7_20trials.after.tg10_rebound.low_pct':
        ('fig7_20trials', 'after', 'TG10 rebound', 'low', 100),
    'scorecard.fig7_20trials.after.tg10_rebound.high_pct':
        ('fig7_20trials', 'after', 'TG10 rebound', 'high', 100),
    'scorecard.fig7_20trials.blend.tg10.value_pct':
        ('fig7_20trials', 'blend', 'TG10', 'value', 100),
    'scorecard.fig7_20trials.blend.tg10.low_pct': ('fig7_20trials', 'blend', 'TG10', 'low', 100),
    'scorecard.fig7_20trials.blend.tg10.high_pct': ('fig7_20trials', 'blend', 'TG10', 'high', 100),
    'scorecard.fig2.stages_home.value':
        ('fig2', 'stages_home', 'deviation from home after epoch 1', 'value'),
    'scorecard.fig2.stages.low_mm':
        ('fig2', 'stages', 'final error at the worse extreme', 'low', 1e3),
    'scorecard.fig2.stages.high_mm':
        ('fig2', 'stages', 'final error at the worse extreme', 'high', 1e3),
    'scorecard.fig7_20trials.final.const1.0.high':
        ('fig7_20trials', 'final', 'const1.0', 'high', 1),
    'scorecard.fig4.final.tg100.value': ('fig4', 'final', 'TG100', 'value', 1),
    'scorecard.fig7_20trials.final.const1.0.value': ('fig7_20trials', 'final', 'const1.0', 'value'),
}
# the readings beside the primary: figure, claim, where, reading, column, scale
CONTROLLED = {
    'grid.fig5.final.tg1000.value':
        ('fig5', 'final', 'TG1000', 'metres, full size two-sided', 'value', 1),
    'grid.fig4.final.const1.0.value':
        ('fig4', 'final', 'const1.0', 'metres, full size two-sided', 'value', 1),
    'grid.fig4.rise.tg1000.value_pct': ('fig4', 'rise', 'TG1000', 'per trial', 'value', 100),
    'grid.fig4.rise.tg1000.low_pct': ('fig4', 'rise', 'TG1000', 'per trial', 'low', 100),
    'grid.fig4.rise.tg1000.high_pct': ('fig4', 'rise', 'TG1000', 'per trial', 'high', 100),
    'uniform.fig5.final.tg1000.value':
        ('fig5', 'final', 'TG1000', 'uniform points, full size two-sided', 'value', 1),
    'uniform.fig7_20trials.final.const1.0.value':
        ('fig7_20trials', 'final', 'const1.0', 'uniform points, full size two-sided', 'value', 1),
    'uniform.fig7_20trials.final.const1.0.high':
        ('fig7_20trials', 'final', 'const1.0', 'uniform points, full size two-sided', 'high', 1),
    'decade.fig7_20trials.final.tg10000.value':
        ('fig7_20trials', 'final', 'TG10000', 'last decade, path targets', 'value', 1),
    'control.fig7_20trials.after.tg10_rebound.value_pct':
        ('fig7_20trials', 'after', 'TG10 rebound', 'controlled', 'value', 100),
    'control.fig7_20trials.after.tg10_rebound.low_pct':
        ('fig7_20trials', 'after', 'TG10 rebound', 'controlled', 'low', 100),
    'control.fig7_20trials.after.tg10_rebound.high_pct':
        ('fig7_20trials', 'after', 'TG10 rebound', 'controlled', 'high', 100),
    'control.fig7_20trials.after.tg10_rebound.control_pct':
        ('fig7_20trials', 'after', 'TG10 rebound', 'controlled', 'control_value', 100),
    'control.fig7_20trials.blend.tg10.value_pct':
        ('fig7_20trials', 'blend', 'TG10', 'controlled', 'value', 100),
    'control.fig7_20trials.blend.tg10.low_pct':
        ('fig7_20trials', 'blend', 'TG10', 'controlled', 'low', 100),
    'control.fig7_20trials.blend.tg10.high_pct':
        ('fig7_20trials', 'blend', 'TG10', 'controlled', 'high', 100),
    'control.fig7_20trials.blend.tg10.control_pct':
        ('fig7_20trials', 'blend', 'TG10', 'controlled', 'control_value', 100),
}
# readings_summary.csv: figure, reading, condition, column, scale
READINGS_SUMMARY = {
    'readings_summary.fig7.least_squares_solver_lstsq.const0.5.final_abs_error_mean_mm':
        ('fig7', 'least squares (solver=lstsq)', 'const0.5', 'final_abs_error_mean', 1e3),
    'readings_summary.fig7.eta_0.1_w.tg10.final_abs_error_mean_mm':
        ('fig7', 'eta = 0.1 / W', 'TG10', 'final_abs_error_mean', 1e3),
    'readings_summary.fig7.eta_0.1_w.const0.5.final_abs_error_mean_mm':
        ('fig7', 'eta = 0.1 / W', 'const0.5', 'final_abs_error_mean', 1e3),
    'readings_summary.fig7.eta_0.3_w.tg1000.final_abs_error_mean_mm':
        ('fig7', 'eta = 0.3 / W', 'TG1000', 'final_abs_error_mean', 1e3),
    'readings_summary.fig7.eta_0.3_w.const1.0.final_abs_error_mean_mm':
        ('fig7', 'eta = 0.3 / W', 'const1.0', 'final_abs_error_mean', 1e3),
    'readings_summary.fig7.least_squares_solver_lstsq.const1.0.final_abs_error_mean_mm':
        ('fig7', 'least squares (solver=lstsq)', 'const1.0', 'final_abs_error_mean', 1e3),
    'readings_summary.fig7.path_evaluation.tg1000.final_abs_error_mean_mm':
        ('fig7', 'path evaluation', 'TG1000', 'final_abs_error_mean', 1e3),
    'readings_summary.fig7.path_evaluation.tg100.final_abs_error_mean_mm':
        ('fig7', 'path evaluation', 'TG100', 'final_abs_error_mean', 1e3),
    'readings_summary.fig7.least_squares_solver_lstsq.tg1000.final_abs_error_mean_mm':
        ('fig7', 'least squares (solver=lstsq)', 'TG1000', 'final_abs_error_mean', 1e3),
    'readings_summary.fig7.least_squares_solver_lstsq.tg10000.final_abs_error_mean_mm':
        ('fig7', 'least squares (solver=lstsq)', 'TG10000', 'final_abs_error_mean', 1e3),
}
# the readings study's final error over the paper's value
QUOTED_RATIOS = {
    'readings_summary.fig4.eta_0.1_w.const1.0.final_abs_error_mean.over.summary.const1.0.paper_final_abs_error':
        ('fig4', 'eta = 0.1 / W', 'const1.0'),
    'readings_summary.fig4.eta_0.1_w.const0.5.final_abs_error_mean.over.summary.const0.5.paper_final_abs_error':
        ('fig4', 'eta = 0.1 / W', 'const0.5'),
    'readings_summary.fig5.eta_0.1_w.const0.5.final_abs_error_mean.over.summary.const0.5.paper_final_abs_error':
        ('fig5', 'eta = 0.1 / W', 'const0.5'),
}
# a reading's worst rise (readings.csv)
QUOTED_RISE = {
    'readings.fig4.eta_0.3_w.rise.value_pct': ('fig4', 'eta = 0.3 / W', 'rise'),
    'readings.fig5.eta_0.3_w.rise.value_pct': ('fig5', 'eta = 0.3 / W', 'rise'),
}
