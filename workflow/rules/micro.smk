# Micro stage: hydration of a compacted pellet (thesis Chap. 3), one job per case.


rule micro_case:
    input:
        porosity=get_micro_porosity,
    output:
        result="results/micro/{case}.nc",
        figure="results/micro/{case}.png",
    params:
        code=script_code("micro_case.py"),
        micro=get_micro_case_config,
        materials=get_micro_materials,
    threads: get_micro_threads
    conda:
        "../envs/claychain.yaml"
    log:
        "results/logs/micro_case/{case}.log",
    benchmark:
        "results/benchmarks/micro_case/{case}.tsv"
    script:
        "../scripts/micro_case.py"


rule micro_compare:
    input:
        expand("results/micro/{case}.nc", case=CASES),
    output:
        figure="results/micro/comparison.png",
    params:
        code=script_code("micro_compare.py"),
    conda:
        "../envs/claychain.yaml"
    log:
        "results/logs/micro_compare/all.log",
    benchmark:
        "results/benchmarks/micro_compare/all.tsv"
    script:
        "../scripts/micro_compare.py"


rule micro_convergence:
    input:
        get_convergence_cases,
    output:
        result="results/studies/convergence.nc",
        figure="results/studies/convergence.png",
    params:
        code=script_code("micro_convergence.py"),
        cases=config["micro"]["studies"]["convergence"],
    conda:
        "../envs/claychain.yaml"
    log:
        "results/logs/micro_convergence/all.log",
    benchmark:
        "results/benchmarks/micro_convergence/all.tsv"
    script:
        "../scripts/micro_convergence.py"


rule micro_scale_realization:
    input:
        porosity=get_micro_porosity,
    output:
        result="results/studies/scale/{realization}.nc",
        figure="results/studies/scale/{realization}.png",
    params:
        code=script_code("micro_case.py"),
        micro=get_scale_realization_config,
        materials=get_micro_materials,
    group:
        "scale"
    conda:
        "../envs/claychain.yaml"
    log:
        "results/logs/micro_scale_realization/{realization}.log",
    benchmark:
        "results/benchmarks/micro_scale_realization/{realization}.tsv"
    script:
        "../scripts/micro_case.py"


rule micro_scale:
    input:
        unpack(get_scale_inputs),
    output:
        result="results/studies/scale.nc",
        figure="results/studies/scale.png",
    params:
        code=script_code("micro_scale.py"),
        layout=get_scale_layout,
    localrule: True
    conda:
        "../envs/claychain.yaml"
    log:
        "results/logs/micro_scale/all.log",
    benchmark:
        "results/benchmarks/micro_scale/all.tsv"
    script:
        "../scripts/micro_scale.py"
