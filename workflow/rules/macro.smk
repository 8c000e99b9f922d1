# Macro stage: the pellet-powder mock-up (thesis Chap. 4) fed by the upscaling table.


rule macro_case:
    """Run one macro mock-up case (or ensemble member) on the permeability table."""
    input:
        table=config["macro"]["table_path"] or UPSCALING_TABLE,
    output:
        result=run_path("macro/{macro_case}.nc"),
        figure=report(
            run_path("macro/{macro_case}.png"),
            caption="../report/macro_case.rst",
            category="4. Macro",
            subcategory="cases",
        ),
    params:
        code=script_code("macro_case.py"),
        macro=get_macro_case_config,
        materials=get_macro_materials,
    threads: get_macro_threads
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/macro_case/{macro_case}.log"),
    benchmark:
        run_path("benchmarks/macro_case/{macro_case}.tsv")
    script:
        "../scripts/macro_case.py"


rule macro_comparison:
    """The macro cases' pressures and suction on one figure."""
    input:
        cases=expand(run_path("macro/{macro_case}.nc"), macro_case=MACRO_CASES),
    output:
        figure=report(
            run_path("macro/comparison.png"),
            caption="../report/macro_comparison.rst",
            category="4. Macro",
            subcategory="cases",
        ),
    params:
        code=script_code("macro_comparison.py"),
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/macro_comparison.log"),
    benchmark:
        run_path("benchmarks/macro_comparison.tsv")
    script:
        "../scripts/macro_comparison.py"


rule macro_ensemble:
    """Statistics (mean, quantile band) over a seed ensemble's members."""
    input:
        members=get_ensemble_members,
    output:
        result=run_path("macro/ensemble_{ensemble}.nc"),
        figure=report(
            run_path("macro/ensemble_{ensemble}.png"),
            caption="../report/macro_ensemble.rst",
            category="4. Macro",
            subcategory="ensembles",
        ),
    params:
        code=script_code("macro_ensemble.py"),
        ensemble=get_ensemble_config,
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/macro_ensemble/{ensemble}.log"),
    benchmark:
        run_path("benchmarks/macro_ensemble/{ensemble}.tsv")
    script:
        "../scripts/macro_ensemble.py"
