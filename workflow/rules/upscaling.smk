# Upscaling: the micro cases' permeability curves -> the pellet permeability table that
# the macro model reads (docs/design.md §2).


rule upscaling_table:
    """Pellet permeability table (per condition, against suction) from the micro cases."""
    input:
        unpack(get_upscaling_sources),
    output:
        table=run_path("upscaling/pellet_permeability.nc"),
        csv=run_path("upscaling/pellet_permeability.csv"),
        figure=report(
            run_path("upscaling/pellet_permeability.png"),
            caption="../report/upscaling.rst",
            category="3. Upscaling",
        ),
    params:
        code=script_code("upscaling_table.py"),
        upscaling=config["upscaling"],
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/upscaling_table/all.log"),
    benchmark:
        run_path("benchmarks/upscaling_table/all.tsv")
    script:
        "../scripts/upscaling_table.py"
