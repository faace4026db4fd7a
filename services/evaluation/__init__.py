"""What `hamnet eval` computes from played episodes: per-episode records, success rates with
confidence intervals, failure reasons, the report (JSON, PNG, comparison between policies) and
the skills analysis of HAMnet's modulation embedding (paper Sec. sec:benchmark and
sec:qualitative-analysis). Pure functions on records and arrays; the runner that plays the
episodes produces their inputs."""
