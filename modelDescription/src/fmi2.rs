//! FMI 2.0 Co-Simulation schema (fmi2ModelDescription.xsd), only the parts this FMU uses.

use super::*;

#[derive(Serialize)]
#[serde(rename = "fmiModelDescription")]
pub(crate) struct ModelDescription {
    #[serde(rename = "@fmiVersion")]
    fmi_version: &'static str,
    #[serde(rename = "@modelName")]
    model_name: &'static str,
    #[serde(rename = "@guid")]
    guid: String,
    #[serde(rename = "@description")]
    description: &'static str,
    #[serde(rename = "@generationTool")]
    generation_tool: &'static str,
    #[serde(rename = "@version")]
    version: &'static str,
    #[serde(rename = "@author")]
    author: &'static str,
    #[serde(rename = "@copyright")]
    copyright: &'static str,
    #[serde(rename = "@license")]
    license: &'static str,
    #[serde(rename = "@generationDateAndTime")]
    generation_date_and_time: String,
    #[serde(rename = "@variableNamingConvention")]
    variable_naming_convention: &'static str,
    #[serde(rename = "CoSimulation")]
    co_simulation: CoSimulation,
    #[serde(rename = "UnitDefinitions")]
    unit_definitions: UnitDefinitions,
    #[serde(rename = "TypeDefinitions")]
    type_definitions: TypeDefinitions,
    #[serde(rename = "LogCategories")]
    log_categories: LogCategories,
    #[serde(rename = "DefaultExperiment")]
    default_experiment: DefaultExperiment,
    #[serde(rename = "ModelVariables")]
    model_variables: ModelVariables,
    #[serde(rename = "ModelStructure")]
    model_structure: ModelStructure,
}

#[derive(Serialize)]
struct CoSimulation {
    #[serde(rename = "@modelIdentifier")]
    model_identifier: &'static str,
    #[serde(rename = "@needsExecutionTool")]
    needs_execution_tool: bool,
    #[serde(rename = "@canHandleVariableCommunicationStepSize")]
    can_handle_variable_communication_step_size: bool,
    #[serde(rename = "@canInterpolateInputs")]
    can_interpolate_inputs: bool,
    #[serde(rename = "@maxOutputDerivativeOrder")]
    max_output_derivative_order: u32,
    /// Spelled as in the FMI 2.0 schema.
    #[serde(rename = "@canRunAsynchronuously")]
    can_run_asynchronuously: bool,
    #[serde(rename = "@canBeInstantiatedOnlyOncePerProcess")]
    can_be_instantiated_only_once_per_process: bool,
    #[serde(rename = "@canNotUseMemoryManagementFunctions")]
    can_not_use_memory_management_functions: bool,
    #[serde(rename = "@canGetAndSetFMUstate")]
    can_get_and_set_fmu_state: bool,
    #[serde(rename = "@canSerializeFMUstate")]
    can_serialize_fmu_state: bool,
    #[serde(rename = "@providesDirectionalDerivative")]
    provides_directional_derivative: bool,
}

#[derive(Serialize)]
struct TypeDefinitions {
    #[serde(rename = "SimpleType")]
    simple_types: Vec<SimpleType>,
}

#[derive(Serialize)]
struct SimpleType {
    #[serde(rename = "@name")]
    name: &'static str,
    #[serde(rename = "@description")]
    description: &'static str,
    #[serde(rename = "Enumeration")]
    enumeration: EnumerationType,
}

#[derive(Serialize)]
struct EnumerationType {
    #[serde(rename = "Item")]
    items: Vec<Item>,
}

#[derive(Serialize)]
struct ModelVariables {
    #[serde(rename = "ScalarVariable")]
    scalar_variables: Vec<ScalarVariable>,
}

#[derive(Serialize)]
struct ScalarVariable {
    #[serde(flatten)]
    common: Common,
    /// The type element (`<Real>`, `<Boolean>`, `<Enumeration>`), named by the variant.
    #[serde(rename = "$value")]
    value: TypedValue,
}

#[derive(Serialize)]
enum TypedValue {
    Real {
        #[serde(rename = "@unit", skip_serializing_if = "Option::is_none")]
        unit: Option<&'static str>,
        #[serde(rename = "@displayUnit", skip_serializing_if = "Option::is_none")]
        display_unit: Option<&'static str>,
        #[serde(rename = "@start", skip_serializing_if = "Option::is_none")]
        start: Option<f64>,
        #[serde(rename = "@min", skip_serializing_if = "Option::is_none")]
        min: Option<f64>,
        #[serde(rename = "@max", skip_serializing_if = "Option::is_none")]
        max: Option<f64>,
    },
    Boolean {
        #[serde(rename = "@start", skip_serializing_if = "Option::is_none")]
        start: Option<bool>,
    },
    Enumeration {
        #[serde(rename = "@declaredType")]
        declared_type: &'static str,
        #[serde(rename = "@start", skip_serializing_if = "Option::is_none")]
        start: Option<i64>,
        #[serde(rename = "@min", skip_serializing_if = "Option::is_none")]
        min: Option<i64>,
        #[serde(rename = "@max", skip_serializing_if = "Option::is_none")]
        max: Option<i64>,
    },
}

#[derive(Serialize)]
struct ModelStructure {
    #[serde(rename = "Outputs")]
    outputs: Unknowns,
    #[serde(rename = "InitialUnknowns")]
    initial_unknowns: Unknowns,
}

#[derive(Serialize)]
struct Unknowns {
    #[serde(rename = "Unknown")]
    unknowns: Vec<Unknown>,
}

#[derive(Serialize)]
struct Unknown {
    /// 1-based position in ModelVariables (not the value reference).
    #[serde(rename = "@index")]
    index: usize,
    /// 1-based indices of the knowns, ascending; "" = depends on none.
    #[serde(rename = "@dependencies")]
    dependencies: String,
}

fn scalar_variable(value_reference: u32, v: &'static Variable) -> ScalarVariable {
    let value = match v.ty {
        VarType::Real => TypedValue::Real {
            unit: v.unit,
            display_unit: v.display_unit,
            start: real_start(v),
            min: v.min,
            max: v.max,
        },
        VarType::Boolean => TypedValue::Boolean { start: boolean_start(v) },
        VarType::Enumeration(declared_type) => TypedValue::Enumeration {
            declared_type,
            start: integer_start(v),
            min: integer_bound(v.min),
            max: integer_bound(v.max),
        },
    };
    ScalarVariable { common: Common::new(value_reference, v), value }
}

/// ModelVariables lists the table in order, so the 1-based index is position + 1.
fn unknowns(rows: &[(u32, Vec<u32>)]) -> Unknowns {
    let index = |vr: u32| table().position(|(r, _)| r == vr).expect("row of the table") + 1;
    let unknown = |(vr, knowns): &(u32, Vec<u32>)| Unknown {
        index: index(*vr),
        dependencies: knowns.iter().map(|&k| index(k).to_string()).collect::<Vec<_>>().join(" "),
    };
    Unknowns { unknowns: rows.iter().map(unknown).collect() }
}

pub(crate) fn model_description() -> ModelDescription {
    ModelDescription {
        fmi_version: "2.0",
        model_name: MODEL_NAME,
        guid: ehsv_actuator::variables::interface_token(),
        description: MODEL_DESCRIPTION,
        generation_tool: GENERATION_TOOL,
        version: VERSION,
        author: AUTHOR,
        copyright: COPYRIGHT,
        license: LICENSE,
        generation_date_and_time: generation_date_and_time(),
        variable_naming_convention: "structured",
        co_simulation: CoSimulation {
            model_identifier: MODEL_IDENTIFIER,
            needs_execution_tool: false,
            can_handle_variable_communication_step_size: true,
            can_interpolate_inputs: true,
            max_output_derivative_order: 1,
            can_run_asynchronuously: false,
            can_be_instantiated_only_once_per_process: false,
            can_not_use_memory_management_functions: true,
            can_get_and_set_fmu_state: true,
            can_serialize_fmu_state: true,
            provides_directional_derivative: false,
        },
        unit_definitions: unit_definitions(),
        type_definitions: TypeDefinitions {
            simple_types: ENUMERATIONS
                .iter()
                .map(|e| SimpleType {
                    name: e.name,
                    description: e.description,
                    enumeration: EnumerationType { items: items(e) },
                })
                .collect(),
        },
        log_categories: log_categories(),
        default_experiment: DEFAULT_EXPERIMENT,
        model_variables: ModelVariables {
            scalar_variables: table().map(|(vr, v)| scalar_variable(vr, v)).collect(),
        },
        model_structure: ModelStructure {
            outputs: unknowns(&dependencies().outputs),
            initial_unknowns: unknowns(&dependencies().initial_unknowns),
        },
    }
}
