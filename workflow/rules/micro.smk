# Micro stage: hydration of a compacted pellet (thesis Chap. 3), one job per case.


rule micro_case:
    """Hydrate one micro case (pellet on the porosity grid): permeability, cracks."""
    input:
        porosity=get_micro_porosity,
    output:
        result=run_path("micro/{case}.nc"),
        figure=report(
            run_path("micro/{case}.png"),
            caption="../report/micro_case.rst",
            category="2. Micro",
            subcategory="cases",
        ),
    params:
        code=script_code("micro_case.py"),
        micro=get_micro_case_config,
        materials=get_micro_materials,
    threads: get_micro_threads
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/micro_case/{case}.log"),
    benchmark:
        run_path("benchmarks/micro_case/{case}.tsv")
    script:
        "../scripts/micro_case.py"


rule micro_compare:
    """Permeability against saturation of all micro cases on one figure."""
    input:
        expand(run_path("micro/{case}.nc"), case=CASES),
    output:
        figure=report(
            run_path("micro/comparison.png"),
            caption="../report/micro_comparison.rst",
            category="2. Micro",
            subcategory="cases",
        ),
    params:
        code=script_code("micro_compare.py"),
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/micro_compare/all.log"),
    benchmark:
        run_path("benchmarks/micro_compare/all.tsv")
    script:
        "../scripts/micro_compare.py"


rule micro_convergence:
    """Convergence study: the convergence cases stacked over their number of points."""
    input:
        get_convergence_cases,
    output:
        result=run_path("studies/convergence.nc"),
        figure=report(
            run_path("studies/convergence.png"),
            caption="../report/micro_convergence.rst",
            category="2. Micro",
            subcategory="convergence study",
        ),
    params:
        code=script_code("micro_convergence.py"),
        cases=config["micro"]["studies"]["convergence"],
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/micro_convergence/all.log"),
    benchmark:
        run_path("benchmarks/micro_convergence/all.tsv")
    script:
        "../scripts/micro_convergence.py"


rule micro_scale_realization:
    """Scale study: hydrate one sub-cube (realization) of the reference case."""
    input:
        porosity=get_micro_porosity,
    output:
        result=run_path("studies/scale/{realization}.nc"),
        figure=report(
            run_path("studies/scale/{realization}.png"),
            caption="../report/micro_scale_realization.rst",
            category="2. Micro",
            subcategory="scale study",
        ),
    params:
        code=script_code("micro_case.py"),
        micro=get_scale_realization_config,
        materials=get_micro_materials,
    group:
        "scale"
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/micro_scale_realization/{realization}.log"),
    benchmark:
        run_path("benchmarks/micro_scale_realization/{realization}.tsv")
    script:
        "../scripts/micro_case.py"


rule micro_scale:
    """Scale study: mean and spread over the realizations per domain fraction."""
    input:
        unpack(get_scale_inputs),
    output:
        result=run_path("studies/scale.nc"),
        figure=report(
            run_path("studies/scale.png"),
            caption="../report/micro_scale.rst",
            category="2. Micro",
            subcategory="scale study",
        ),
    params:
        code=script_code("micro_scale.py"),
        layout=get_scale_layout,
    localrule: True
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/micro_scale/all.log"),
    benchmark:
        run_path("benchmarks/micro_scale/all.tsv")
    script:
        "../scripts/micro_scale.py"
