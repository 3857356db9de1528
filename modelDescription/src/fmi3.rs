//! FMI 3.0 Co-Simulation schema (fmi3ModelDescription.xsd), only the parts this FMU uses.

use super::*;

#[derive(Serialize)]
#[serde(rename = "fmiModelDescription")]
pub(crate) struct ModelDescription {
    #[serde(rename = "@fmiVersion")]
    fmi_version: &'static str,
    #[serde(rename = "@modelName")]
    model_name: &'static str,
    #[serde(rename = "@instantiationToken")]
    instantiation_token: String,
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

/// Attribute names as in fmi3InterfaceType.xsd (note `FMUState`, `providesDirectionalDerivatives`).
#[derive(Serialize)]
struct CoSimulation {
    #[serde(rename = "@modelIdentifier")]
    model_identifier: &'static str,
    #[serde(rename = "@needsExecutionTool")]
    needs_execution_tool: bool,
    #[serde(rename = "@canBeInstantiatedOnlyOncePerProcess")]
    can_be_instantiated_only_once_per_process: bool,
    #[serde(rename = "@canGetAndSetFMUState")]
    can_get_and_set_fmu_state: bool,
    #[serde(rename = "@canSerializeFMUState")]
    can_serialize_fmu_state: bool,
    #[serde(rename = "@providesDirectionalDerivatives")]
    provides_directional_derivatives: bool,
    #[serde(rename = "@providesAdjointDerivatives")]
    provides_adjoint_derivatives: bool,
    #[serde(rename = "@canHandleVariableCommunicationStepSize")]
    can_handle_variable_communication_step_size: bool,
    #[serde(rename = "@maxOutputDerivativeOrder")]
    max_output_derivative_order: u32,
    #[serde(rename = "@providesIntermediateUpdate")]
    provides_intermediate_update: bool,
    #[serde(rename = "@canReturnEarlyAfterIntermediateUpdate")]
    can_return_early_after_intermediate_update: bool,
    #[serde(rename = "@hasEventMode")]
    has_event_mode: bool,
    #[serde(rename = "@providesEvaluateDiscreteStates")]
    provides_evaluate_discrete_states: bool,
}

#[derive(Serialize)]
struct TypeDefinitions {
    #[serde(rename = "EnumerationType")]
    enumeration_types: Vec<EnumerationType>,
}

#[derive(Serialize)]
struct EnumerationType {
    #[serde(rename = "@name")]
    name: &'static str,
    #[serde(rename = "@description")]
    description: &'static str,
    #[serde(rename = "Item")]
    items: Vec<Item>,
}

#[derive(Serialize)]
struct ModelVariables {
    /// Each variable is an element named by its type (`<Float64>`, `<Boolean>`, `<Enumeration>`).
    #[serde(rename = "$value")]
    variables: Vec<ModelVariable>,
}

#[derive(Serialize)]
enum ModelVariable {
    Float64 {
        #[serde(flatten)]
        common: Common,
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
        #[serde(flatten)]
        common: Common,
        #[serde(rename = "@start", skip_serializing_if = "Option::is_none")]
        start: Option<bool>,
    },
    Enumeration {
        #[serde(flatten)]
        common: Common,
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
    #[serde(rename = "Output")]
    outputs: Vec<Unknown>,
    #[serde(rename = "InitialUnknown")]
    initial_unknowns: Vec<Unknown>,
}

#[derive(Serialize)]
struct Unknown {
    #[serde(rename = "@valueReference")]
    value_reference: u32,
    /// Value references of the knowns, ascending; "" = depends on none.
    #[serde(rename = "@dependencies")]
    dependencies: String,
}

fn model_variable(value_reference: u32, v: &'static Variable) -> ModelVariable {
    let common = Common::new(value_reference, v);
    match v.ty {
        VarType::Real => ModelVariable::Float64 {
            common,
            unit: v.unit,
            display_unit: v.display_unit,
            start: real_start(v),
            min: v.min,
            max: v.max,
        },
        VarType::Boolean => ModelVariable::Boolean { common, start: boolean_start(v) },
        VarType::Enumeration(declared_type) => ModelVariable::Enumeration {
            common,
            declared_type,
            start: integer_start(v),
            min: integer_bound(v.min),
            max: integer_bound(v.max),
        },
    }
}

fn unknowns(rows: &[(u32, Vec<u32>)]) -> Vec<Unknown> {
    let unknown = |(vr, knowns): &(u32, Vec<u32>)| Unknown {
        value_reference: *vr,
        dependencies: knowns.iter().map(u32::to_string).collect::<Vec<_>>().join(" "),
    };
    rows.iter().map(unknown).collect()
}

pub(crate) fn model_description() -> ModelDescription {
    ModelDescription {
        fmi_version: "3.0",
        model_name: MODEL_NAME,
        instantiation_token: ehsv_actuator::variables::interface_token(),
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
            can_be_instantiated_only_once_per_process: false,
            can_get_and_set_fmu_state: true,
            can_serialize_fmu_state: true,
            provides_directional_derivatives: false,
            provides_adjoint_derivatives: false,
            can_handle_variable_communication_step_size: true,
            max_output_derivative_order: 1,
            provides_intermediate_update: false,
            can_return_early_after_intermediate_update: false,
            has_event_mode: false,
            provides_evaluate_discrete_states: false,
        },
        unit_definitions: unit_definitions(),
        type_definitions: TypeDefinitions {
            enumeration_types: ENUMERATIONS
                .iter()
                .map(|e| EnumerationType {
                    name: e.name,
                    description: e.description,
                    items: items(e),
                })
                .collect(),
        },
        log_categories: log_categories(),
        default_experiment: DEFAULT_EXPERIMENT,
        model_variables: ModelVariables {
            variables: table().map(|(vr, v)| model_variable(vr, v)).collect(),
        },
        model_structure: ModelStructure {
            outputs: unknowns(&dependencies().outputs),
            initial_unknowns: unknowns(&dependencies().initial_unknowns),
        },
    }
}
