"""The paper's studies, apart from the pipeline's machinery: its claims and their verdicts, the
readings of its text, the explanations, the baselines, the open choices, the reporting
conventions and the figures that draw them. They read aggregated tables; none runs a trial."""
